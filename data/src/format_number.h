// Numbers in the data library's error messages (private to data/src).
#pragma once

#include <cstdio>
#include <string>

namespace strokelab::data_internal {

// Nine significant digits: enough to tell apart the values a user wrote.
inline std::string Num(double value) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.9g", value);
  return buffer;
}

}  // namespace strokelab::data_internal
