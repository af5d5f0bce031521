// Reads a JSON file of the regression folder (a job or a baseline); a parse error fails the test.
#pragma once

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

namespace strokelab::testing {

inline nlohmann::json ReadJson(const std::filesystem::path& path) {
  std::ifstream in(path);
  return nlohmann::json::parse(in);
}

}  // namespace strokelab::testing
