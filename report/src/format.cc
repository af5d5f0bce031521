#include "format.h"

#include <cstdarg>
#include <cstdio>

namespace strokelab::report {

std::string Format(const char* format, ...) {
  // Sized by a first pass, so that long captions (record names are the user's) are never cut.
  va_list args, copy;
  va_start(args, format);
  va_copy(copy, args);
  const int size = std::vsnprintf(nullptr, 0, format, copy);
  va_end(copy);
  std::string text(size > 0 ? static_cast<size_t>(size) : 0, '\0');
  if (size > 0) std::vsnprintf(text.data(), text.size() + 1, format, args);
  va_end(args);
  return text;
}

}  // namespace strokelab::report
