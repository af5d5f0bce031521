#include "zip_reader.h"

#include <zlib.h>

#include <algorithm>
#include <cstdio>
#include <stdexcept>

namespace strokelab::server {
namespace {

constexpr uint32_t kLocalSignature = 0x04034b50, kCentralSignature = 0x02014b50, kEndSignature = 0x06054b50,
                   kZip64LocatorSignature = 0x07064b50, kDescriptorSignature = 0x08074b50;
constexpr size_t kLocalSize = 30, kCentralSize = 46, kEndSize = 22, kZip64LocatorSize = 20, kMaxComment = 0xffff;
constexpr uint16_t kFlagsEncrypted = 0x0001 | 0x0040 | 0x2000;  // traditional, strong, central directory
constexpr uint16_t kFlagDescriptor = 0x0008;
constexpr uint16_t kFlagsAccepted = 0x0002 | 0x0004 | kFlagDescriptor | 0x0800;  // deflate level, UTF-8 name
constexpr uint16_t kStored = 0, kDeflated = 8;
constexpr uint32_t kZip64Marker = 0xffffffff;
// Unix st_mode file types, as zip writers on Unix hosts store them in the external attributes.
constexpr uint32_t kUnixTypeMask = 0170000, kUnixFile = 0100000, kUnixDirectory = 0040000, kUnixLink = 0120000;
constexpr uint64_t kRatioFloorBytes = 1 << 20;  // smaller members cannot be large bombs

// A little-endian number of `bytes` bytes at `at` (the caller has checked the bounds).
uint32_t Le(std::string_view s, size_t at, size_t bytes) {
  uint32_t value = 0;
  for (size_t i = bytes; i-- > 0;) value = value << 8 | static_cast<unsigned char>(s[at + i]);
  return value;
}

std::string Hex(uint32_t value) {
  char text[16];
  std::snprintf(text, sizeof text, "%08x", value);
  return text;
}

// A central directory entry, checked against its local header.
struct Entry {
  std::string where, path;
  bool directory = false, keep = false;
  uint16_t method = 0;
  uint32_t crc = 0;
  uint64_t compressed = 0, size = 0;
  size_t start = 0, data = 0, end = 0;  // local header, compressed data, past data and descriptor
};

size_t FindEndRecord(std::string_view archive) {
  if (archive.size() < kEndSize)
    throw ArchiveError("truncated: " + std::to_string(archive.size()) + " bytes, less than a zip's end record");
  const size_t last = archive.size() - kEndSize;
  const size_t first = last > kMaxComment ? last - kMaxComment : 0;
  for (size_t at = last + 1; at-- > first;)
    if (Le(archive, at, 4) == kEndSignature && at + kEndSize + Le(archive, at + 20, 2) == archive.size()) return at;
  throw ArchiveError("no end of central directory record (truncated, or not a zip archive)");
}

// The member's type from a Unix mode, when the writer stored one; throws for links and devices.
bool IsUnixDirectory(uint16_t made_by, uint32_t external, const std::string& where) {
  const unsigned host = made_by >> 8;
  const uint32_t type = (external >> 16) & kUnixTypeMask;
  if ((host != 3 && host != 19) || type == 0 || type == kUnixFile) return false;  // 3 Unix, 19 OS X
  if (type == kUnixDirectory) return true;
  throw ArchiveError(where + ": is " + (type == kUnixLink ? "a symbolic link" : "a device, FIFO or socket") +
                     " (only regular files and directories are accepted)");
}

// Where the member's data end: past the data descriptor when flag bit 3 says there is one (with or
// without its optional signature); it must repeat the central directory's CRC-32 and sizes.
size_t DataEnd(std::string_view archive, size_t limit, const Entry& e, bool descriptor) {
  const size_t at = e.data + e.compressed;
  if (!descriptor) return at;
  const auto matches = [&](size_t d) {
    return d + 12 <= limit && Le(archive, d, 4) == e.crc && Le(archive, d + 4, 4) == e.compressed &&
           Le(archive, d + 8, 4) == e.size;
  };
  if (at + 4 <= limit && Le(archive, at, 4) == kDescriptorSignature && matches(at + 4)) return at + 16;
  if (matches(at)) return at + 12;
  throw ArchiveError(e.where + ": its data descriptor is missing or disagrees with the central directory");
}

// Checks the local header of `e` (whose central fields are set) and sets e.data and e.end.
void ReadLocalHeader(std::string_view archive, size_t cd_offset, std::string_view name, uint16_t flags, Entry& e) {
  if (e.start > cd_offset || cd_offset - e.start < kLocalSize || Le(archive, e.start, 4) != kLocalSignature)
    throw ArchiveError(e.where + ": no local header at offset " + std::to_string(e.start) + " (corrupt archive)");
  const size_t name_length = Le(archive, e.start + 26, 2), extra_length = Le(archive, e.start + 28, 2);
  e.data = e.start + kLocalSize + name_length + extra_length;
  if (e.data > cd_offset || e.compressed > cd_offset - e.data)
    throw ArchiveError(e.where + ": truncated (its data run into the central directory)");
  if (archive.substr(e.start + kLocalSize, name_length) != name)
    throw ArchiveError(e.where + ": the local header names another file (corrupt archive)");
  if (Le(archive, e.start + 18, 4) == kZip64Marker || Le(archive, e.start + 22, 4) == kZip64Marker)
    throw ArchiveError(e.where + ": zip64 sizes in its local header (not accepted)");
  const bool descriptor = flags & kFlagDescriptor;
  // With a data descriptor the local CRC and sizes may be zero (written before the data were).
  const auto agrees = [&](size_t at, uint64_t central) {
    const uint32_t local = Le(archive, e.start + at, 4);
    return local == central || (descriptor && local == 0);
  };
  if (Le(archive, e.start + 6, 2) != flags || Le(archive, e.start + 8, 2) != e.method || !agrees(14, e.crc) ||
      !agrees(18, e.compressed) || !agrees(22, e.size))
    throw ArchiveError(e.where + ": the local header disagrees with the central directory (corrupt archive)");
  e.end = DataEnd(archive, cd_offset, e, descriptor);
}

// The central directory entry at `at` (the directory spans [cd_offset, cd_end)), checked with its
// local header; `at` moves past it.
Entry ReadEntry(std::string_view archive, size_t& at, size_t cd_offset, size_t cd_end, size_t index,
                const ArchiveLimits& limits, MemberTally& tally) {
  if (cd_end - at < kCentralSize || Le(archive, at, 4) != kCentralSignature)
    throw ArchiveError("central directory entry " + std::to_string(index + 1) + " is missing or corrupt");
  const size_t name_length = Le(archive, at + 28, 2);
  const size_t entry_size = kCentralSize + name_length + Le(archive, at + 30, 2) + Le(archive, at + 32, 2);
  if (cd_end - at < entry_size)
    throw ArchiveError("central directory entry " + std::to_string(index + 1) + " runs past the central directory");
  const std::string_view name = archive.substr(at + kCentralSize, name_length);
  Entry e;
  e.where = MemberWhere(index, name);
  const uint16_t flags = Le(archive, at + 8, 2);
  e.method = Le(archive, at + 10, 2);
  e.crc = Le(archive, at + 16, 4);
  e.compressed = Le(archive, at + 20, 4);
  e.size = Le(archive, at + 24, 4);
  e.start = Le(archive, at + 42, 4);
  if (flags & kFlagsEncrypted) throw ArchiveError(e.where + ": encrypted (not accepted)");
  if (flags & ~kFlagsAccepted)
    throw ArchiveError(e.where + ": general-purpose flags 0x" + Hex(flags) + " (not supported)");
  if (e.method != kStored && e.method != kDeflated)
    throw ArchiveError(e.where + ": compression method " + std::to_string(e.method) +
                       " (only 0, stored, and 8, deflate, are accepted)");
  if (e.compressed == kZip64Marker || e.size == kZip64Marker || e.start == kZip64Marker)
    throw ArchiveError(e.where + ": zip64 sizes or offset (not accepted)");
  if (Le(archive, at + 34, 2) != 0) throw ArchiveError(e.where + ": on another disk (multi-disk archives are not accepted)");
  e.directory = IsUnixDirectory(Le(archive, at + 4, 2), Le(archive, at + 38, 4), e.where) ||
                (!name.empty() && name.back() == '/');
  e.path = NormaliseMemberName(name, e.where, limits);
  e.keep = tally.Add(e.where, e.path, e.directory, e.size);
  if (e.method == kStored && e.compressed != e.size)
    throw ArchiveError(e.where + ": stored, but its sizes differ (" + std::to_string(e.compressed) + " and " +
                       std::to_string(e.size) + " bytes)");
  if (e.size > kRatioFloorBytes && e.size / std::max<uint64_t>(1, limits.max_ratio) > e.compressed)
    throw ArchiveError(e.where + ": inflates " + std::to_string(e.compressed) + " bytes to " + std::to_string(e.size) +
                       ", over " + std::to_string(limits.max_ratio) + " times as many (a zip bomb)");
  ReadLocalHeader(archive, cd_offset, name, flags, e);
  at += entry_size;
  return e;
}

// The central directory's entries (offset and size from the end record at `end`).
std::vector<Entry> ReadCentralDirectory(std::string_view archive, size_t end, const ArchiveLimits& limits) {
  const uint32_t entries = Le(archive, end + 10, 2), cd_size = Le(archive, end + 12, 4), cd_offset = Le(archive, end + 16, 4);
  if (entries == 0xffff || cd_size == kZip64Marker || cd_offset == kZip64Marker ||
      (end >= kZip64LocatorSize && Le(archive, end - kZip64LocatorSize, 4) == kZip64LocatorSignature))
    throw ArchiveError("a zip64 archive (not accepted)");
  if (Le(archive, end + 4, 2) != 0 || Le(archive, end + 6, 2) != 0 || Le(archive, end + 8, 2) != entries)
    throw ArchiveError("a multi-disk archive (not accepted)");
  if (uint64_t{cd_offset} + cd_size != end)
    throw ArchiveError("the central directory (" + std::to_string(cd_size) + " bytes at offset " +
                       std::to_string(cd_offset) + ") does not end where the end record starts, at " +
                       std::to_string(end) + " (truncated or corrupt archive)");
  MemberTally tally(limits, /*directories_may_repeat=*/false);
  std::vector<Entry> result;
  size_t at = cd_offset;
  for (size_t index = 0; index < entries; ++index)
    result.push_back(ReadEntry(archive, at, cd_offset, end, index, limits, tally));
  if (at != end) throw ArchiveError("the central directory holds more than its " + std::to_string(entries) + " entries");
  // The ratio rule on the archive as a whole (issue 15): 250 members of 1 MiB each, none over the
  // per-member floor, inflated 262 MB from a 638 KB archive.
  uint64_t inflated = 0;
  for (const Entry& e : result) inflated += e.size;
  if (inflated > kRatioFloorBytes && inflated / std::max<uint64_t>(1, limits.max_ratio) > archive.size())
    throw ArchiveError("the members inflate to " + std::to_string(inflated) + " bytes, over " +
                       std::to_string(limits.max_ratio) + " times the archive's " + std::to_string(archive.size()) +
                       " (a zip bomb)");
  return result;
}

// Refuses members whose bytes overlap: the overlapping-file bomb inflates one stream many times.
void CheckNoOverlap(const std::vector<Entry>& entries) {
  std::vector<const Entry*> by_start;
  for (const Entry& e : entries) by_start.push_back(&e);
  std::sort(by_start.begin(), by_start.end(), [](const Entry* a, const Entry* b) { return a->start < b->start; });
  for (size_t i = 1; i < by_start.size(); ++i)
    if (by_start[i]->start < by_start[i - 1]->end)
      throw ArchiveError(by_start[i]->where + ": overlaps " + by_start[i - 1]->where + " (a zip bomb, or corrupt)");
}

// The deflate stream `in` inflated to exactly `size` bytes. The buffer has one byte more than
// declared: a stream that fills it is longer than declared, and is stopped there.
std::string Inflate(std::string_view in, uint64_t size, const std::string& where) {
  std::string out(size + 1, '\0');
  z_stream z{};
  if (inflateInit2(&z, -MAX_WBITS) != Z_OK) throw std::runtime_error("zlib: inflateInit2 failed");
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(in.data()));
  z.avail_in = static_cast<uInt>(in.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  const int rc = inflate(&z, Z_FINISH);
  const uint64_t produced = z.total_out, unused = z.avail_in;
  const std::string zlib_message = z.msg ? z.msg : "";
  inflateEnd(&z);
  if (rc == Z_MEM_ERROR) throw std::bad_alloc();
  if (produced > size)
    throw ArchiveError(where + ": inflates to more than its declared " + std::to_string(size) +
                       " bytes (a zip bomb, or corrupt)");
  if (rc == Z_DATA_ERROR) throw ArchiveError(where + ": corrupt deflate data (" + zlib_message + ")");
  if (rc != Z_STREAM_END)
    throw ArchiveError(where + ": truncated deflate data (" + std::to_string(produced) + " of " +
                       std::to_string(size) + " bytes)");
  if (produced != size)
    throw ArchiveError(where + ": inflates to " + std::to_string(produced) + " bytes, not its declared " +
                       std::to_string(size));
  if (unused != 0)
    throw ArchiveError(where + ": " + std::to_string(unused) + " bytes after the end of its deflate stream");
  out.resize(size);
  return out;
}

}  // namespace

bool LooksLikeZip(std::string_view archive) {
  return archive.substr(0, 4) == std::string_view("PK\3\4", 4) || archive.substr(0, 4) == std::string_view("PK\5\6", 4);
}

std::vector<ZipMember> ReadZip(std::string_view archive, const ArchiveLimits& limits) {
  const std::vector<Entry> entries = ReadCentralDirectory(archive, FindEndRecord(archive), limits);
  CheckNoOverlap(entries);
  std::vector<ZipMember> members;
  for (const Entry& e : entries) {
    const std::string_view data = archive.substr(e.data, e.compressed);
    std::string bytes = e.method == kStored ? std::string(data) : Inflate(data, e.size, e.where);
    const uint32_t crc = static_cast<uint32_t>(crc32_z(0, reinterpret_cast<const Bytef*>(bytes.data()), bytes.size()));
    if (crc != e.crc)
      throw ArchiveError(e.where + ": CRC-32 mismatch (stored " + Hex(e.crc) + ", computed " + Hex(crc) +
                         "): corrupt archive");
    if (e.keep) members.push_back({e.path, e.directory, e.directory ? std::string() : std::move(bytes)});
  }
  return members;
}

}  // namespace strokelab::server
