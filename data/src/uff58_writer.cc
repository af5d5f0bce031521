// Writing UFF dataset 58 (strokelab/data/uff58.h): an evenly spaced real time series, ASCII (4E20.12)
// or binary 58b (little-endian IEEE doubles), in the layout pyuff and the I-DEAS description use.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "strokelab/base/errors.h"
#include "strokelab/data/uff58.h"

namespace strokelab {
namespace {

// printf into a string.
template <class... Args>
void AppendFormatted(std::string* out, const char* format, Args... args) {
  char buffer[256];
  const int n = std::snprintf(buffer, sizeof buffer, format, args...);
  out->append(buffer, static_cast<size_t>(n < 0 ? 0 : std::min<int>(n, sizeof buffer - 1)));
}

std::string UffText(const std::string& text, size_t width) {
  std::string out = text.substr(0, width);
  for (char& c : out)
    if (c == '\n' || c == '\r') c = ' ';
  return out.empty() ? "NONE" : out;
}

}  // namespace

void AppendUff58(std::string* out, const UffWriteSeries& series, bool binary) {
  if (!series.values || series.values->empty()) throw InputError("values", "a dataset 58 needs at least one value");
  if (!(series.sample_rate_hz > 0) || !std::isfinite(series.sample_rate_hz))
    throw InputError("sample_rate_hz", "must be a finite number > 0");
  const std::vector<double>& values = *series.values;
  const size_t n = values.size();
  out->append("    -1\n");
  if (binary)
    AppendFormatted(out, "%6d%c%6d%6d%12d%12zu%6d%6d%12d%12d\n", 58, 'b', 1, 2, 11, n * 8, 0, 0, 0, 0);
  else
    out->append("    58\n");
  AppendFormatted(out, "%-80s\n", UffText(series.id1, 80).c_str());
  for (int i = 0; i < 4; ++i) out->append("NONE\n");
  AppendFormatted(out, "%5d%10d%5d%10d %-10s%10d%4d %-10s%10d%4d\n", 1, 0, 0, 0, "NONE", series.response_node,
                  series.response_direction, "NONE", 0, 0);
  AppendFormatted(out, "%10d%10zu%10d%13.5E%13.6E%13.5E\n", 4, n, 1, 0.0, 1.0 / series.sample_rate_hz, 0.0);
  AppendFormatted(out, "%10d%5d%5d%5d %-20s %-20s\n", 17, 0, 0, 0, "Time", "s");
  AppendFormatted(out, "%10d%5d%5d%5d %-20s %-20s\n", series.ordinate_data_type, 0, 0, 0,
                  UffText(series.id1, 20).c_str(), UffText(series.ordinate_units, 20).c_str());
  AppendFormatted(out, "%10d%5d%5d%5d %-20s %-20s\n", 0, 0, 0, 0, "NONE", "NONE");
  AppendFormatted(out, "%10d%5d%5d%5d %-20s %-20s\n", 0, 0, 0, 0, "NONE", "NONE");
  if (binary) {
    // Little-endian doubles, directly followed by the closing "-1" line (as pyuff writes them).
    const size_t start = out->size();
    out->resize(start + n * 8);
    char* p = out->data() + start;
    for (double value : values) {
      std::uint64_t bits = std::bit_cast<std::uint64_t>(value);
      if constexpr (std::endian::native == std::endian::big) bits = __builtin_bswap64(bits);
      std::memcpy(p, &bits, 8);
      p += 8;
    }
  } else {
    for (size_t i = 0; i < n; ++i) {
      AppendFormatted(out, "%20.12E", values[i]);
      if (i % 4 == 3 || i + 1 == n) out->push_back('\n');
    }
  }
  out->append("    -1\n");
}

}  // namespace strokelab
