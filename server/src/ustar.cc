#include "ustar.h"

#include <algorithm>
#include <limits>

namespace strokelab::server {
namespace {

constexpr size_t kBlock = 512;

// Header fields (offset, length) of POSIX.1-1988 ustar.
struct Field {
  size_t offset, length;
};
constexpr Field kName{0, 100}, kSize{124, 12}, kChecksum{148, 8}, kType{156, 1}, kMagic{257, 6}, kVersion{263, 2},
    kPrefix{345, 155};

std::string_view Raw(std::string_view block, Field f) { return block.substr(f.offset, f.length); }

// A NUL-terminated (or full-width) text field.
std::string_view Text(std::string_view block, Field f) {
  std::string_view s = Raw(block, f);
  return s.substr(0, std::min(s.size(), s.find('\0')));
}

bool IsZeroBlock(std::string_view block) {
  return std::all_of(block.begin(), block.end(), [](char c) { return c == '\0'; });
}

// An octal field: optional leading blanks, octal digits, then NULs or blanks to the end.
uint64_t ParseOctal(std::string_view field, const std::string& what) {
  if (!field.empty() && (static_cast<unsigned char>(field[0]) & 0x80))
    throw ArchiveError(what + " is a base-256 number (over 8 GiB): not accepted");
  size_t i = 0;
  while (i < field.size() && field[i] == ' ') ++i;
  uint64_t value = 0;
  bool digits = false;
  for (; i < field.size() && field[i] >= '0' && field[i] <= '7'; ++i) {
    if (value > (std::numeric_limits<uint64_t>::max() >> 3)) throw ArchiveError(what + " overflows");
    value = value * 8 + static_cast<uint64_t>(field[i] - '0');
    digits = true;
  }
  for (; i < field.size(); ++i)
    if (field[i] != '\0' && field[i] != ' ') throw ArchiveError(what + " is not an octal number");
  if (!digits) throw ArchiveError(what + " is empty");
  return value;
}

void CheckChecksum(std::string_view block, const std::string& where) {
  const uint64_t stored = ParseOctal(Raw(block, kChecksum), where + ": header checksum");
  uint64_t unsigned_sum = 0;
  int64_t signed_sum = 0;
  for (size_t i = 0; i < kBlock; ++i) {
    const bool in_field = i >= kChecksum.offset && i < kChecksum.offset + kChecksum.length;
    const char c = in_field ? ' ' : block[i];
    unsigned_sum += static_cast<unsigned char>(c);
    signed_sum += static_cast<signed char>(c);
  }
  if (stored != unsigned_sum && static_cast<int64_t>(stored) != signed_sum)
    throw ArchiveError(where + ": header checksum mismatch (stored " + std::to_string(stored) + ", computed " +
                       std::to_string(unsigned_sum) + "): corrupt archive");
}

// The records "LEN key=value\n" of a pax extended header; returns the "path" record, if any.
// Records other than path and the time and owner annotations are refused when they would change
// what is extracted (size, linkpath).
std::string PaxPath(std::string_view data, const std::string& where) {
  std::string path;
  while (!data.empty()) {
    const size_t space = data.find(' ');
    if (space == std::string_view::npos || space == 0 || space > 20)
      throw ArchiveError(where + ": malformed pax record");
    uint64_t length = 0;
    for (char c : data.substr(0, space)) {
      if (c < '0' || c > '9') throw ArchiveError(where + ": malformed pax record length");
      length = length * 10 + static_cast<uint64_t>(c - '0');
    }
    if (length <= space + 1 || length > data.size() || data[length - 1] != '\n')
      throw ArchiveError(where + ": malformed pax record");
    const std::string_view record = data.substr(space + 1, length - space - 2);
    const size_t equals = record.find('=');
    if (equals == std::string_view::npos) throw ArchiveError(where + ": malformed pax record");
    const std::string_view key = record.substr(0, equals), value = record.substr(equals + 1);
    if (key == "path") path = std::string(value);
    else if (key == "size" || key == "linkpath" || key.rfind("GNU.sparse", 0) == 0)
      throw ArchiveError(where + ": pax record '" + std::string(key) + "' is not accepted");
    data.remove_prefix(length);
  }
  return path;
}

}  // namespace

std::vector<TarMember> ReadUstar(std::string_view archive, const ArchiveLimits& limits) {
  std::vector<TarMember> members;
  MemberTally tally(limits, /*directories_may_repeat=*/true);
  std::string pending_name;  // from a pax 'x' header or a GNU 'L' long name, for the next member
  size_t offset = 0;
  for (size_t index = 0;; ++index) {
    if (offset == archive.size())
      throw ArchiveError("truncated: the archive ends without its end-of-archive (zero) block");
    if (archive.size() - offset < kBlock)
      throw ArchiveError("truncated: " + std::to_string(archive.size() - offset) + " bytes left at offset " +
                         std::to_string(offset) + ", less than a 512-byte header");
    const std::string_view block = archive.substr(offset, kBlock);
    if (IsZeroBlock(block)) {
      if (!pending_name.empty()) throw ArchiveError("an extended header is not followed by a member");
      break;  // end of archive; what follows (the second zero block, record padding) is ignored
    }
    const std::string_view header_name = Text(block, kName);
    const std::string where = MemberWhere(index, header_name);
    const std::string_view magic = Raw(block, kMagic);
    if (magic.substr(0, 5) != "ustar")
      throw ArchiveError(where + ": no ustar magic at offset " + std::to_string(offset) +
                         " (not a tar archive, or a pre-POSIX one)");
    CheckChecksum(block, where);
    // POSIX ustar ("ustar\0" "00") has a name prefix; GNU tar ("ustar " " \0") uses those bytes otherwise.
    const bool posix = magic == std::string_view("ustar\0", 6) && Raw(block, kVersion) == "00";
    const uint64_t size = ParseOctal(Raw(block, kSize), where + ": size");
    const uint64_t padded = (size + kBlock - 1) / kBlock * kBlock;
    offset += kBlock;
    if (padded > archive.size() - offset)
      throw ArchiveError(where + ": truncated (its data needs " + std::to_string(size) + " bytes, " +
                         std::to_string(archive.size() - offset) + " are left)");
    const std::string_view data = archive.substr(offset, size);
    offset += padded;

    const char type = block[kType.offset];
    if (type == 'x') {
      pending_name = PaxPath(data, where);
      continue;
    }
    if (type == 'g') {
      (void)PaxPath(data, where);  // global records: checked, a global path is ignored
      continue;
    }
    if (type == 'L') {
      pending_name = std::string(data.substr(0, std::min(data.size(), data.find('\0'))));
      continue;
    }
    std::string name(header_name);
    if (!pending_name.empty()) {
      name = pending_name;
      pending_name.clear();
    } else if (posix && !Text(block, kPrefix).empty()) {
      name = std::string(Text(block, kPrefix)) + "/" + name;
    }
    const std::string where_full = MemberWhere(index, name);
    const bool directory = type == '5';
    if (!directory && type != '0' && type != '\0' && type != '7') {
      const char* what = type == '1' ? "a hard link"
                         : type == '2' ? "a symbolic link"
                         : type == '3' || type == '4' ? "a device"
                         : type == '6' ? "a FIFO"
                         : type == 'S' ? "a sparse file"
                                       : "of an unknown type";
      throw ArchiveError(where_full + ": is " + std::string(what) + " (only regular files and directories are accepted)");
    }
    const std::string path = NormaliseMemberName(name, where_full, limits);
    if (!tally.Add(where_full, path, directory, size)) continue;
    members.push_back({path, directory, directory ? std::string_view() : data});
  }
  return members;
}

}  // namespace strokelab::server
