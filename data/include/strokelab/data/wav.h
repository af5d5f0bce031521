// Multi-channel WAV (RIFF WAVE) files, as data acquisition systems and rigs export time series: read
// and written.
//
// Read: PCM integers of 16, 24 or 32 bits and IEEE floats of 32 bits (format tag 1 or 3, or
// WAVE_FORMAT_EXTENSIBLE 0xFFFE with one of those as its subformat), any number of channels. The
// "fmt " chunk must come before "data"; chunks of other types (LIST, fact, cue, ...) are skipped, with
// their pad byte when odd. A sample is returned as a fraction of full scale: integers divided by
// 2^(bits - 1) (in [-1, 1)), floats as stored. WAV holds no units: the mapping file
// (strokelab/data/mapping.h) says what full scale is in volts.
//
// Errors are InputError whose field is "FILE:byte N" (N: the offset in the file, from 0, of the chunk
// or value that is wrong) or "FILE" and whose message names the chunk.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace strokelab {

enum class WavSampleFormat { kInt16, kInt24, kInt32, kFloat32 };
const char* ToString(WavSampleFormat format);  // "int16", "int24", "int32", "float32"
// "int16", "pcm16", ... "float32"; throws InputError(field) for other text.
WavSampleFormat ParseWavSampleFormat(const std::string& text, const std::string& field);
// Bits per sample.
int WavBits(WavSampleFormat format);

struct WavFile {
  WavSampleFormat format = WavSampleFormat::kInt16;
  std::uint32_t sample_rate_hz = 0;               // [Hz]
  std::vector<std::vector<double>> channels;      // [channel][frame], fractions of full scale
};

// Parses `bytes`, the content of `file` (named in errors). Throws InputError (see above).
WavFile ParseWav(std::string_view bytes, const std::string& file);

// A WAV file of `channels` (equal lengths, fractions of full scale) in `format`: integers rounded to
// the nearest code and clipped to the code range, floats rounded to float. Throws InputError for
// unequal or empty channels or non-finite values.
std::string EncodeWav(const std::vector<const std::vector<double>*>& channels, std::uint32_t sample_rate_hz,
                      WavSampleFormat format);

}  // namespace strokelab
