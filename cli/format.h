// Numbers in the CLI's text reports.
#pragma once

#include <cmath>
#include <cstdio>
#include <string>

namespace strokelab::cli {

// printf's "%.<digits>g", or "-" for a value that is not finite (an unknown standard error).
inline std::string General(double value, int digits) {
  if (!std::isfinite(value)) return "-";
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%.*g", digits, value);
  return buffer;
}

}  // namespace strokelab::cli
