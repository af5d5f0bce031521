// Sweep jobs for fault tests, and the check that each ended right whatever was done to the service
// meanwhile: every job succeeded with exactly its points (each grid point once, no row twice, each
// task's rows 0..n-1 once in the file) and bit for bit the rows and saturation map of a
// single-process `strokelab sweep` on the same grid; the file passes SQLite's integrity check.
//
// Grids differ from job to job (frequency points first_frequency_points + 7 k) so that no job is
// served from the result cache of another.
#pragma once

#include <gtest/gtest.h>

#include <set>
#include <string>
#include <vector>

#include "process/service.h"
#include "process/store_file.h"
#include "process/sweep_checks.h"

namespace strokelab::test_fault {

using namespace strokelab::test_process;

class SweepWorkload {
 public:
  SweepWorkload(int first_frequency_points, int amplitude_points, bool thresholds)
      : first_frequency_points_(first_frequency_points), amplitude_points_(amplitude_points), thresholds_(thresholds) {}

  // Submits the next grid; returns its id.
  int64_t SubmitNext(httplib::Client& client) {
    const int f = first_frequency_points_ + 7 * static_cast<int>(jobs_.size());
    jobs_.push_back({Submit(client, SweepJob(f, amplitude_points_, thresholds_)), f, 0});
    return jobs_.back().id;
  }
  // Jobs of this workload still queued or running, as the file says (the server may be dead).
  int Unfinished(Db& file) const {
    int n = 0;
    for (const Job& j : jobs_)
      n += file.One("SELECT status IN ('queued', 'running') FROM jobs WHERE id = " + std::to_string(j.id)) == "1";
    return n;
  }
  size_t size() const { return jobs_.size(); }

  // Waits for every job and checks its rows through the API; `dir` holds the reference runs. Then
  // CheckFile on the database (while the server runs, or on a copy after it stopped).
  void WaitAndCheck(httplib::Client& client, const fs::path& dir, double timeout_s) {
    for (Job& j : jobs_) {
      const json done = WaitForFinish(client, j.id, timeout_s);
      ASSERT_EQ(done.at("status"), "succeeded") << done.dump();
      EXPECT_EQ(done.at("progress").at("done"), done.at("progress").at("total")) << done.dump();
      j.tasks = done.at("progress").at("total");
      const std::vector<json> points = FetchPoints(client, j.id);
      const std::string what = "job " + std::to_string(j.id) + " (" + std::to_string(j.frequency_points) + " x " +
                               std::to_string(amplitude_points_) + ")";
      SCOPED_TRACE(what);
      ExpectEachGridPointOnce(points, static_cast<size_t>(j.frequency_points) * amplitude_points_);
      const json reference = CliSweep(dir, j.frequency_points, amplitude_points_);
      ExpectSameRows(points, reference.at("points"), what + " points");
      if (thresholds_) ExpectSameMap(client, j.id, reference);
    }
  }
  void WaitAndCheck(httplib::Client& client, const fs::path& dir, const fs::path& db, double timeout_s) {
    WaitAndCheck(client, dir, timeout_s);
    CheckFile(db);
  }

  // In the file: every task of every job done, with one block per table it has rows of (a second
  // completion would fail the block's UNIQUE key), the points rows adding up to the job's points
  // counter; SQLite's integrity check passes.
  void CheckFile(const fs::path& db) const {
    Db file(db);
    for (const Job& j : jobs_) {
      const std::string id = std::to_string(j.id);
      EXPECT_EQ(file.One("SELECT count(*) FROM tasks WHERE job_id = " + id + " AND status != 'done'"), "0");
      const auto per_task = file.Query("SELECT task_idx, count(*), count(DISTINCT table_name) FROM result_blocks "
                                       "WHERE job_id = " + id + " GROUP BY task_idx");
      for (const auto& t : per_task) EXPECT_EQ(t[1], t[2]) << "job " << id << " task " << t[0];
      EXPECT_EQ(per_task.size(), size_t(j.tasks)) << "job " << id << ": tasks with rows";
      EXPECT_EQ(file.One("SELECT sum(rows) FROM result_blocks WHERE table_name = 'points' AND job_id = " + id),
                file.One("SELECT points FROM jobs WHERE id = " + id));
    }
    EXPECT_EQ(file.One("PRAGMA integrity_check"), "ok");
  }

 private:
  struct Job {
    int64_t id;
    int frequency_points;
    int tasks = 0;  // known once finished
  };

  int first_frequency_points_, amplitude_points_;
  bool thresholds_;
  std::vector<Job> jobs_;
};

}  // namespace strokelab::test_fault
