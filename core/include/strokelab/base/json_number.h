// A double as JSON. JSON has no NaN or infinity: a non-finite value ("not found", "not measured")
// is written as null, which every reader of strokelab's JSON takes as "no number".
#pragma once

#include <cmath>
#include <nlohmann/json.hpp>

namespace strokelab {

inline nlohmann::json JsonNumber(double value) {
  return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(nullptr);
}

}  // namespace strokelab
