// Checks of a sweep job's stored rows against a single-process `strokelab sweep --json`: bit for
// bit equality, each grid point exactly once, the same saturation map.
#pragma once

#include <gtest/gtest.h>

#include <cstring>
#include <map>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "process/service.h"

namespace strokelab::test_process {

// Equality of two JSON values with numbers compared bit for bit (and by JSON number type), so
// that 0.1 and 0.1 + 1 ulp, or -0.0 and 0.0, differ.
inline bool BitwiseEqual(const json& a, const json& b) {
  if (a.type() != b.type()) return false;
  switch (a.type()) {
    case json::value_t::number_float: {
      const double x = a.get<double>(), y = b.get<double>();
      return std::memcmp(&x, &y, sizeof x) == 0;
    }
    case json::value_t::object: {
      if (a.size() != b.size()) return false;
      for (auto it = a.begin(); it != a.end(); ++it)
        if (!b.contains(it.key()) || !BitwiseEqual(it.value(), b.at(it.key()))) return false;
      return true;
    }
    case json::value_t::array: {
      if (a.size() != b.size()) return false;
      for (size_t i = 0; i < a.size(); ++i)
        if (!BitwiseEqual(a[i], b[i])) return false;
      return true;
    }
    default: return a == b;
  }
}

// Checks that `got` is `want` row for row (the store pages rows in task order, tasks are planned
// in amplitude order, and a task's rows are in the core's order: the CLI's order). Reports the
// first difference.
inline void ExpectSameRows(const std::vector<json>& got, const json& want, const std::string& what) {
  EXPECT_EQ(got.size(), want.size()) << what << ": row count";
  const size_t n = std::min(got.size(), want.size());
  size_t differing = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!BitwiseEqual(got[i], want[i])) {
      if (differing++ == 0)
        ADD_FAILURE() << what << ": first difference at row " << i << ":\n  service: " << got[i].dump()
                      << "\n  single process: " << want[i].dump();
    }
  }
  EXPECT_EQ(differing, 0u) << what << ": rows that differ";
}

// Up and down rows: exactly one per grid point and branch; no row (with all its values) twice.
inline void ExpectEachGridPointOnce(const std::vector<json>& rows, size_t grid_points) {
  std::map<std::string, std::set<std::pair<double, double>>> by_branch;
  std::map<std::tuple<double, double, std::string>, int> count;
  std::set<std::string> distinct_rows;
  for (const json& p : rows) {
    const double f = p.at("frequency_hz"), a = p.at("amplitude_v");
    const std::string branch = p.at("branch");
    by_branch[branch].insert({f, a});
    ++count[{f, a, branch}];
    distinct_rows.insert(p.dump());
  }
  EXPECT_EQ(by_branch["up"].size(), grid_points);
  EXPECT_EQ(by_branch["down"].size(), grid_points);
  for (const auto& [key, n] : count) {
    if (std::get<2>(key) != "unstable") {
      EXPECT_EQ(n, 1) << std::get<2>(key) << " at " << std::get<0>(key) << " Hz, " << std::get<1>(key) << " V";
    }
  }
  EXPECT_EQ(distinct_rows.size(), rows.size()) << "some rows are stored twice";
}

// The single-process reference: `strokelab sweep ... --json` on the same grid.
inline json CliSweep(const fs::path& dir, int frequency_points, int amplitude_points) {
  Child cli({STROKELAB_BINARY, "sweep", "--model", "paper", "--frequency-hz", "5:50", "--frequency-points",
             std::to_string(frequency_points), "--amplitude-v", "0.1:0.6", "--amplitude-points",
             std::to_string(amplitude_points), "--threads", "2", "--json"},
            dir / "cli-sweep.log");
  const int code = cli.WaitExit(60);
  if (code != 0) throw std::runtime_error("strokelab sweep exited with " + std::to_string(code) + ":\n" + cli.Log());
  return json::parse(cli.Out());
}

// Checks the saturation map (thresholds per frequency, jump intervals) against the reference.
inline void ExpectSameMap(httplib::Client& c, int64_t id, const json& reference) {
  const json map = GetJson(c, "/v1/jobs/" + std::to_string(id) + "/saturation-map");
  const json& thresholds = map.at("saturation_threshold");
  std::vector<json> got(thresholds.begin(), thresholds.end());
  ExpectSameRows(got, reference.at("saturation_threshold"), "saturation thresholds");
  std::vector<json> jumps(map.at("jump").begin(), map.at("jump").end());
  ExpectSameRows(jumps, reference.at("jump"), "jump intervals");
}

}  // namespace strokelab::test_process
