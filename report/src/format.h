// printf into a std::string, for the reports' captions and cells (private to report/src).
#pragma once

#include <string>

namespace strokelab::report {

std::string Format(const char* format, ...) __attribute__((format(printf, 1, 2)));

}  // namespace strokelab::report
