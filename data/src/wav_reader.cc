// Reading WAV files (strokelab/data/wav.h): the RIFF chunks walked with every size checked against
// the file, "fmt " parsed, "data" decoded to fractions of full scale; other chunks skipped.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include "strokelab/base/errors.h"
#include "strokelab/data/wav.h"

namespace strokelab {
namespace {

std::uint32_t ReadLe32(const unsigned char* p) {
  return static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) << 8 |
         static_cast<std::uint32_t>(p[2]) << 16 | static_cast<std::uint32_t>(p[3]) << 24;
}
std::uint16_t ReadLe16(const unsigned char* p) { return static_cast<std::uint16_t>(p[0] | p[1] << 8); }

// A chunk id as printable text for messages.
std::string ChunkName(const unsigned char* p) {
  std::string out = "'";
  for (int i = 0; i < 4; ++i) out += (p[i] >= 0x20 && p[i] < 0x7f) ? static_cast<char>(p[i]) : '?';
  return out + "'";
}

constexpr std::uint16_t kFormatPcm = 1, kFormatFloat = 3, kFormatExtensible = 0xFFFE;

}  // namespace

const char* ToString(WavSampleFormat format) {
  switch (format) {
    case WavSampleFormat::kInt16: return "int16";
    case WavSampleFormat::kInt24: return "int24";
    case WavSampleFormat::kInt32: return "int32";
    case WavSampleFormat::kFloat32: return "float32";
  }
  return "?";
}

WavSampleFormat ParseWavSampleFormat(const std::string& text, const std::string& field) {
  if (text == "int16" || text == "pcm16") return WavSampleFormat::kInt16;
  if (text == "int24" || text == "pcm24") return WavSampleFormat::kInt24;
  if (text == "int32" || text == "pcm32") return WavSampleFormat::kInt32;
  if (text == "float32" || text == "float") return WavSampleFormat::kFloat32;
  throw InputError(field, "unknown WAV sample format '" + text + "' (int16, int24, int32, float32)");
}

int WavBits(WavSampleFormat format) {
  switch (format) {
    case WavSampleFormat::kInt16: return 16;
    case WavSampleFormat::kInt24: return 24;
    case WavSampleFormat::kInt32:
    case WavSampleFormat::kFloat32: return 32;
  }
  return 0;
}

WavFile ParseWav(std::string_view bytes, const std::string& file) {
  const auto* const data = reinterpret_cast<const unsigned char*>(bytes.data());
  const size_t size = bytes.size();
  const auto error = [&](size_t byte, const std::string& message) -> InputError {
    return InputError(file + ":byte " + std::to_string(byte), message);
  };
  if (size < 12 || std::memcmp(data, "RIFF", 4) != 0 || std::memcmp(data + 8, "WAVE", 4) != 0)
    throw InputError(file, "not a WAV file (no RIFF/WAVE header in its first 12 bytes)");
  WavFile out;
  bool have_format = false;
  std::uint16_t channels = 0, bits = 0, block_align = 0;
  size_t at = 12;
  while (true) {
    if (at + 8 > size) {
      if (at < size) throw error(at, "truncated chunk header: " + std::to_string(size - at) + " bytes left, a chunk header takes 8");
      throw InputError(file, have_format ? "no 'data' chunk" : "no 'fmt ' chunk");
    }
    const std::string name = ChunkName(data + at);
    const std::uint32_t chunk_size = ReadLe32(data + at + 4);
    const size_t body = at + 8;
    if (chunk_size > size - body)
      throw error(at, "chunk " + name + ": size " + std::to_string(chunk_size) + " runs past the end of the file (" +
                          std::to_string(size - body) + " bytes follow its header)");
    if (std::memcmp(data + at, "fmt ", 4) == 0) {
      if (chunk_size < 16) throw error(at, "chunk 'fmt ': size " + std::to_string(chunk_size) + ", at least 16 expected");
      std::uint16_t tag = ReadLe16(data + body);
      channels = ReadLe16(data + body + 2);
      out.sample_rate_hz = ReadLe32(data + body + 4);
      block_align = ReadLe16(data + body + 12);
      bits = ReadLe16(data + body + 14);
      if (tag == kFormatExtensible) {
        if (chunk_size < 40)
          throw error(at, "chunk 'fmt ': WAVE_FORMAT_EXTENSIBLE needs 40 bytes, the chunk has " + std::to_string(chunk_size));
        tag = ReadLe16(data + body + 24);  // the subformat GUID's first two bytes
      }
      if (tag != kFormatPcm && tag != kFormatFloat)
        throw error(body, "chunk 'fmt ': format tag " + std::to_string(tag) + " is not supported (1 PCM, 3 IEEE float)");
      if (channels == 0) throw error(body + 2, "chunk 'fmt ': 0 channels");
      if (out.sample_rate_hz == 0) throw error(body + 4, "chunk 'fmt ': sample rate 0 Hz");
      if (tag == kFormatFloat && bits == 32)
        out.format = WavSampleFormat::kFloat32;
      else if (tag == kFormatPcm && bits == 16)
        out.format = WavSampleFormat::kInt16;
      else if (tag == kFormatPcm && bits == 24)
        out.format = WavSampleFormat::kInt24;
      else if (tag == kFormatPcm && bits == 32)
        out.format = WavSampleFormat::kInt32;
      else
        throw error(body + 14, std::string("chunk 'fmt ': ") + std::to_string(bits) + "-bit " +
                                   (tag == kFormatFloat ? "float" : "PCM") +
                                   " samples are not supported (PCM 16, 24, 32 bits; float 32 bits)");
      if (block_align != channels * (bits / 8))
        throw error(body + 12, "chunk 'fmt ': block align " + std::to_string(block_align) + ", expected " +
                                   std::to_string(channels) + " channels x " + std::to_string(bits / 8) + " bytes");
      have_format = true;
    } else if (std::memcmp(data + at, "data", 4) == 0) {
      if (!have_format) throw error(at, "chunk 'data' comes before the 'fmt ' chunk");
      if (chunk_size % block_align != 0)
        throw error(at, "chunk 'data': size " + std::to_string(chunk_size) + " is not a whole number of frames of " +
                            std::to_string(block_align) + " bytes");
      const size_t frames = chunk_size / block_align;
      const size_t width = bits / 8;
      out.channels.assign(channels, std::vector<double>(frames));
      const unsigned char* p = data + body;
      for (size_t f = 0; f < frames; ++f) {
        for (size_t c = 0; c < channels; ++c, p += width) {
          double value = 0.0;
          switch (out.format) {
            case WavSampleFormat::kInt16:
              value = static_cast<std::int16_t>(ReadLe16(p)) / 32768.0;
              break;
            case WavSampleFormat::kInt24: {
              std::int32_t v = p[0] | p[1] << 8 | p[2] << 16;
              if (v & 0x800000) v -= 0x1000000;
              value = v / 8388608.0;
              break;
            }
            case WavSampleFormat::kInt32:
              value = static_cast<std::int32_t>(ReadLe32(p)) / 2147483648.0;
              break;
            case WavSampleFormat::kFloat32: {
              const std::uint32_t raw = ReadLe32(p);
              float sample;
              std::memcpy(&sample, &raw, 4);
              value = sample;
              if (!std::isfinite(value))
                throw error(static_cast<size_t>(p - data), "chunk 'data': frame " + std::to_string(f + 1) +
                                                               " of channel " + std::to_string(c + 1) + " is not finite");
              break;
            }
          }
          out.channels[c][f] = value;
        }
      }
      if (frames < 1) throw error(at, "chunk 'data' holds no samples");
      return out;
    }
    at = body + chunk_size + (chunk_size & 1u);  // chunks are padded to an even size
    if (at > size) at = size;
  }
}

}  // namespace strokelab
