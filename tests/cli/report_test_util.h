// Helpers of the report tests (files written by the report library, read back).
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "strokelab/identify/fit.h"

namespace strokelab::testing {

inline std::string ReadFile(const std::filesystem::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

inline std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// A folder `name` under the test's temporary directory, removed if it exists.
inline std::filesystem::path FreshDir(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::path(::testing::TempDir()) / name;
  std::filesystem::remove_all(dir);
  return dir;
}

// A fitted parameter with its standard error, as a diagnosis's tables hold it.
inline FitParameter Parameter(std::string name, std::string unit, double value, double standard_error) {
  FitParameter p;
  p.name = std::move(name);
  p.unit = std::move(unit);
  p.value = value;
  p.standard_error = standard_error;
  return p;
}

}  // namespace strokelab::testing
