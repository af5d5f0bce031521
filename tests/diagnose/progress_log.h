// A diagnosis's progress reports (DiagnoseOptions::progress), kept for the tests to check its plan.
#pragma once

#include <gtest/gtest.h>
#include <set>
#include <vector>

#include "strokelab/base/progress.h"

namespace strokelab::testing {

struct ProgressLog {
  std::vector<ProgressStage> reports;

  ProgressHook Hook() {
    return [this](const ProgressStage& s) { reports.push_back(s); };
  }
  // The stage numbers never go back, none is past the plan of its own report, and the diagnosis's N
  // once it has run (`progress_stages`: the maps' stages follow) holds them all.
  void ExpectConsistent(int progress_stages) const {
    ASSERT_FALSE(reports.empty());
    for (size_t i = 0; i < reports.size(); ++i) {
      EXPECT_LE(reports[i].stage, reports[i].stages) << reports[i].name;
      if (i > 0) {
        EXPECT_GE(reports[i].stage, reports[i - 1].stage) << reports[i].name;
      }
    }
    EXPECT_GE(progress_stages, reports.back().stage);
  }
  size_t DistinctStages() const {
    std::set<int> stages;
    for (const ProgressStage& s : reports) stages.insert(s.stage);
    return stages.size();
  }
};

}  // namespace strokelab::testing
