// The quiet NaN that stands for a value not available (not measured, not identifiable, not reached),
// and infinity, the bound that is none. One definition of each for the library: its files compile as
// unity sources, where file-scope copies clash.
#pragma once

#include <limits>

namespace strokelab {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
inline constexpr double kInf = std::numeric_limits<double>::infinity();

}  // namespace strokelab
