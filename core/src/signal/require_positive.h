// The signal stage's check of a rate or frequency argument (private to core/src/signal).
#pragma once

#include <cmath>
#include <sstream>

#include "strokelab/base/errors.h"

namespace strokelab::signal_internal {

inline void RequirePositiveFinite(double value, const char* field) {
  if (!std::isfinite(value) || value <= 0.0) {
    std::ostringstream message;
    message << "must be a finite number > 0 (got " << value << ")";
    throw InputError(field, message.str());
  }
}

}  // namespace strokelab::signal_internal
