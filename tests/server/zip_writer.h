// A zip writer for the tests (zlib's raw deflate and crc32), independent of the reader under test,
// so that no zip program is needed. Each entry can lie (CRC, size, flags, method, data, offset) to
// build the broken archives the reader must refuse.
#pragma once

#include <zlib.h>

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace strokelab::server::zip_writer {

struct ZipEntry {
  ZipEntry(std::string name_, std::string data_) : name(std::move(name_)), data(std::move(data_)) {}
  std::string name, data;
  uint16_t method = 8;                    // 8 deflates `data`; any other method stores it as is
  bool descriptor = false;                // flag bit 3: CRC and sizes in a data descriptor
  bool descriptor_signature = true;       // the descriptor's optional signature
  uint32_t mode = 0100644;                // Unix mode (high 16 bits of the external attributes)
  uint16_t flags = 0;                     // more general-purpose flags
  std::optional<uint32_t> crc, size;      // declared instead of the true ones
  std::optional<std::string> packed;      // the compressed bytes, instead of `data` compressed
  std::optional<uint32_t> local_offset;   // the central entry points there; no local record written
};

inline std::string Le(uint64_t value, int bytes) {
  std::string out;
  for (int i = 0; i < bytes; ++i) out += static_cast<char>((value >> (8 * i)) & 0xff);
  return out;
}

inline uint32_t Crc(std::string_view data) {
  return static_cast<uint32_t>(crc32_z(0, reinterpret_cast<const Bytef*>(data.data()), data.size()));
}

// Raw deflate (no zlib header), as zip stores it; `flush` Z_FULL_FLUSH leaves the stream open.
inline std::string RawDeflate(z_stream& z, std::string_view data, int flush) {
  std::string out;
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  z.avail_in = static_cast<uInt>(data.size());
  char buffer[65536];
  do {
    z.next_out = reinterpret_cast<Bytef*>(buffer);
    z.avail_out = sizeof buffer;
    if (deflate(&z, flush) == Z_STREAM_ERROR) throw std::runtime_error("deflate failed");
    out.append(buffer, sizeof buffer - z.avail_out);
  } while (z.avail_out == 0);
  return out;
}

// Level 1: the fastest (a campaign's CSVs are megabytes); the reader sees the same format at any level.
inline std::string Deflate(std::string_view data) {
  z_stream z{};
  deflateInit2(&z, 1, Z_DEFLATED, -MAX_WBITS, 8, Z_DEFAULT_STRATEGY);
  std::string out = RawDeflate(z, data, Z_FINISH);
  deflateEnd(&z);
  return out;
}

// A deflate stream of `mib` MiB of zeros, built in milliseconds: one fully flushed MiB (which refers
// to nothing before it) repeated, then the final block.
inline std::string DeflatedZeros(size_t mib) {
  z_stream z{};
  deflateInit2(&z, 9, Z_DEFLATED, -MAX_WBITS, 8, Z_DEFAULT_STRATEGY);
  const std::string chunk = RawDeflate(z, std::string(1 << 20, '\0'), Z_FULL_FLUSH);
  const std::string end = RawDeflate(z, "", Z_FINISH);
  deflateEnd(&z);
  std::string out;
  for (size_t i = 0; i < mib; ++i) out += chunk;
  return out + end;
}

inline std::string Zip(const std::vector<ZipEntry>& entries, std::string_view comment = "") {
  std::string local, central;
  for (const ZipEntry& e : entries) {
    const std::string packed = e.packed ? *e.packed : e.method == 8 ? Deflate(e.data) : e.data;
    const std::string sizes = Le(e.crc.value_or(Crc(e.data)), 4) + Le(packed.size(), 4) + Le(e.size.value_or(e.data.size()), 4);
    // version needed 2.0, flags, method, time 00:00, date 1980-01-01
    const std::string common = Le(20, 2) + Le(e.flags | (e.descriptor ? 8 : 0), 2) + Le(e.method, 2) + Le(0, 2) + Le(0x21, 2);
    const uint32_t offset = e.local_offset.value_or(static_cast<uint32_t>(local.size()));
    if (!e.local_offset) {
      local += Le(0x04034b50, 4) + common + (e.descriptor ? std::string(12, '\0') : sizes) + Le(e.name.size(), 2) +
               Le(0, 2) + e.name + packed;
      if (e.descriptor) local += (e.descriptor_signature ? Le(0x08074b50, 4) : "") + sizes;
    }
    // made by Unix (3) zip 2.0; name, extra, comment lengths; disk; internal and external attributes
    central += Le(0x02014b50, 4) + Le(0x0314, 2) + common + sizes + Le(e.name.size(), 2) + Le(0, 2) + Le(0, 2) +
               Le(0, 2) + Le(0, 2) + Le(uint64_t{e.mode} << 16, 4) + Le(offset, 4) + e.name;
  }
  return local + central + Le(0x06054b50, 4) + Le(0, 2) + Le(0, 2) + Le(entries.size(), 2) + Le(entries.size(), 2) +
         Le(central.size(), 4) + Le(local.size(), 4) + Le(comment.size(), 2) + std::string(comment);
}

}  // namespace strokelab::server::zip_writer
