// A double as JSON. JSON has no NaN or infinity: a non-finite value ("not found", "not measured")
// is written as null, which every reader of strokelab's JSON takes as "no number".
#pragma once

#include <cmath>
#include <nlohmann/json.hpp>
#include <vector>

namespace strokelab {

inline nlohmann::json JsonNumber(double value) {
  return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(nullptr);
}

// The values as a JSON array, each as JsonNumber writes it.
inline nlohmann::json JsonNumbers(const std::vector<double>& values) {
  nlohmann::json out = nlohmann::json::array();
  for (double v : values) out.push_back(JsonNumber(v));
  return out;
}

}  // namespace strokelab
