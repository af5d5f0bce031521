// Helpers of the report tests (files written by the report library, read back).
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "strokelab/identify/fit.h"
#include "strokelab/report/diagnosis_maps.h"
#include "strokelab/sweep/sweep.h"

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

// A map on the grid of MapsOf (5, 10, 20 Hz x 0.1, 0.3 V), every point stable on the up branch with
// the spike factor `spikes` x (1 + frequency index): the two maps below span different ranges.
inline SweepResult MapOf(const std::vector<double>& grazing_v, const std::vector<double>& lowest_v, double spikes,
                  std::vector<JumpInterval> jumps) {
  SweepResult r;
  r.frequency_hz = GridAxis{5, 20, 3, true}.Values();
  r.amplitude_v = {0.1, 0.3};
  for (double v : r.amplitude_v) {
    for (size_t j = 0; j < r.frequency_hz.size(); ++j) {
      SweepPoint p;
      p.frequency_hz = r.frequency_hz[j];
      p.amplitude_v = v;
      p.first_harmonic_force_n = 0.5;
      p.peak_force_n = 0.5 * spikes * static_cast<double>(1 + j);
      r.points.push_back(p);
    }
  }
  for (size_t j = 0; j < r.frequency_hz.size(); ++j) r.saturation_threshold.push_back({r.frequency_hz[j], grazing_v[j], lowest_v[j]});
  r.jump = std::move(jumps);
  return r;
}

inline report::DiagnosisMaps MapsOf() {
  report::DiagnosisMaps m;
  m.frequency_hz = {5, 20, 3, true};
  m.amplitude_v = {0.1, 0.3, 2, false};
  m.base = MapOf({0.3, 0.2, NAN}, {0.28, 0.19, NAN}, 1.0, {{0.3, 10, 14, "fold", "grazing"}});
  m.diagnosed = MapOf({0.27, 0.21, 0.4}, {0.25, 0.2, 0.38}, 2.0, {});
  m.seconds = 1.5;
  return m;
}

}  // namespace strokelab::testing
