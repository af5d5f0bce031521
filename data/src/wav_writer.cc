// Writing WAV files (strokelab/data/wav.h): RIFF, "fmt " (PCM or IEEE float) and "data", channels
// interleaved, little-endian.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "strokelab/base/errors.h"
#include "strokelab/data/wav.h"

namespace strokelab {
namespace {

void PutLe(std::string* out, std::uint32_t value, int bytes) {
  for (int i = 0; i < bytes; ++i) out->push_back(static_cast<char>((value >> (8 * i)) & 0xFF));
}

// `fraction` of full scale as the nearest integer code of `bits` bits, clipped to the code range.
std::uint32_t WavCode(double fraction, int bits) {
  const double scale = std::ldexp(1.0, bits - 1);
  const double code = std::clamp(std::nearbyint(fraction * scale), -scale, scale - 1.0);
  return static_cast<std::uint32_t>(static_cast<std::int64_t>(code));
}

}  // namespace

std::string EncodeWav(const std::vector<const std::vector<double>*>& channels, std::uint32_t sample_rate_hz,
                      WavSampleFormat format) {
  if (channels.empty() || channels.size() > 65535) throw InputError("channels", "a WAV file holds 1 to 65535 channels");
  const size_t frames = channels.front()->size();
  if (frames == 0) throw InputError("channels", "no samples");
  for (const auto* channel : channels) {
    if (channel->size() != frames) throw InputError("channels", "channels of unequal length");
    for (double value : *channel)
      if (!std::isfinite(value)) throw InputError("channels", "a non-finite sample");
  }
  if (sample_rate_hz == 0) throw InputError("sample_rate_hz", "must be > 0");
  const int bits = WavBits(format);
  const std::uint32_t block_align = static_cast<std::uint32_t>(channels.size() * static_cast<size_t>(bits / 8));
  const unsigned long long data_bytes = static_cast<unsigned long long>(frames) * block_align;
  if (data_bytes > 0xFFFFFFFFull - 36) throw InputError("channels", "too many samples for one WAV file (4 GB)");
  std::string out;
  out.reserve(44 + data_bytes);
  out += "RIFF";
  PutLe(&out, static_cast<std::uint32_t>(36 + data_bytes), 4);
  out += "WAVEfmt ";
  PutLe(&out, 16, 4);
  PutLe(&out, format == WavSampleFormat::kFloat32 ? 3 : 1, 2);
  PutLe(&out, static_cast<std::uint32_t>(channels.size()), 2);
  PutLe(&out, sample_rate_hz, 4);
  PutLe(&out, sample_rate_hz * block_align, 4);
  PutLe(&out, block_align, 2);
  PutLe(&out, static_cast<std::uint32_t>(bits), 2);
  out += "data";
  PutLe(&out, static_cast<std::uint32_t>(data_bytes), 4);
  for (size_t f = 0; f < frames; ++f) {
    for (const auto* channel : channels) {
      const double value = (*channel)[f];
      if (format == WavSampleFormat::kFloat32) {
        const float sample = static_cast<float>(value);
        std::uint32_t raw;
        std::memcpy(&raw, &sample, 4);
        PutLe(&out, raw, 4);
      } else {
        PutLe(&out, WavCode(value, bits), bits / 8);
      }
    }
  }
  return out;
}

}  // namespace strokelab
