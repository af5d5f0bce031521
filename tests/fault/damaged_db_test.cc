// A damaged or locked database file: the server must refuse to start, with a message that names
// the file and says what is wrong, and a non-zero exit code; never crash, never start on an empty
// database in its place, never change the file. A lock held by another process is waited for
// (SQLite's busy timeout) and then refused; once the lock is gone the server starts on the data.
//
//   header overwritten, random bytes in pages (seeded), truncated mid-page and at half its pages,
//   a text file: refused, file unchanged. Locked by BEGIN EXCLUSIVE in this process: refused, then
//   starts when released; told to stop (SIGTERM) while it waits: stops, does not hang.
#include <gtest/gtest.h>
#include <signal.h>

#include <fstream>
#include <random>

#include "fault/fault_seed.h"
#include "fault/sweep_workload.h"

namespace strokelab::test_fault {
namespace {

// A database with a finished job in it (about 15 pages), checkpointed and closed cleanly.
fs::path MakeGoodDatabase(const fs::path& dir) {
  const fs::path db = dir / "good.db";
  Server server = StartServer(dir, "serve-good", {"--workers", "1", "--db", db.string(), "--quiet"});
  auto client = Client(server);
  const int64_t id = Submit(*client, SweepJob(60, 4, false));
  if (WaitForFinish(*client, id, 60).at("status") != "succeeded") throw std::runtime_error("the seed job failed");
  server.child->Signal(SIGTERM);
  if (server.child->WaitExit(20) != 0) throw std::runtime_error("serve-good did not stop:\n" + server.child->Log());
  return db;
}

void Overwrite(const fs::path& file, uintmax_t offset, const std::string& bytes) {
  std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
  f.seekp(static_cast<std::streamoff>(offset));
  f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

std::string RandomBytes(std::mt19937_64& rng, size_t n) {
  std::string s(n, '\0');
  for (char& c : s) c = static_cast<char>(rng() & 0xff);
  return s;
}

// Starts a server on `db` and expects it to refuse: exit code 1..127, stderr naming the file and
// one of `reasons`; the file unchanged. Returns the message.
std::string ExpectRefused(const fs::path& dir, const fs::path& db, const std::vector<std::string>& reasons) {
  const std::string before = ReadFile(db);
  Child server({STROKELAB_BINARY, "serve", "--port", "0", "--workers", "1", "--db", db.string()},
               dir / (db.filename().string() + ".log"));
  const int code = server.WaitExit(30);
  const std::string log = server.Log();
  EXPECT_GE(code, 1) << log;
  EXPECT_LT(code, 128) << "killed by a signal:\n" << log;
  EXPECT_EQ(log.find("strokelab serving"), std::string::npos) << log;
  EXPECT_NE(log.find(db.string()), std::string::npos) << "the message does not name the file:\n" << log;
  bool said = false;
  for (const std::string& r : reasons) said = said || log.find(r) != std::string::npos;
  EXPECT_TRUE(said) << "no reason of the expected kind:\n" << log;
  EXPECT_TRUE(ReadFile(db) == before) << db << " was changed";
  return log;
}

TEST(DamagedDatabase, RefusedWithAClearMessage) {
  const auto test_start = Clock::now();
  std::mt19937_64 rng(FaultSeed("DamagedDatabase", 5));
  ScratchDir dir("strokelab-fault-db");
  const fs::path good = MakeGoodDatabase(dir.path());
  const uintmax_t size = fs::file_size(good), page = 4096;
  ASSERT_GE(size, 8 * page);
  const std::vector<std::string> damaged = {"not a database", "malformed", "damaged"};
  int refused = 0, tried = 0;
  auto copy = [&](const std::string& name) {
    const fs::path p = dir.path() / name;
    fs::copy_file(good, p, fs::copy_options::overwrite_existing);
    ++tried;
    return p;
  };
  auto check = [&](const fs::path& db, const std::vector<std::string>& reasons) {
    const std::string log = ExpectRefused(dir.path(), db, reasons);
    refused += !::testing::Test::HasFailure();
    std::printf("  %-22s %s", db.filename().c_str(), log.c_str());
  };

  {  // The header's magic string and page size.
    const fs::path db = copy("header.db");
    Overwrite(db, 0, RandomBytes(rng, 24));
    check(db, damaged);
  }
  // Random bytes over the start of a random page other than the first: its b-tree header and cell
  // pointers (or a freelist or overflow link). Bytes inside row contents are not detectable: SQLite
  // keeps no checksums of them (a damaged row fails when read, with a 500 naming the problem).
  for (int round = 0; round < 4; ++round) {
    const fs::path db = copy("page-start-" + std::to_string(round) + ".db");
    const uintmax_t n = std::uniform_int_distribution<uintmax_t>(1, size / page - 1)(rng);
    Overwrite(db, n * page, RandomBytes(rng, 64));
    check(db, damaged);
  }
  {  // Truncated inside a page, and to half of its pages.
    const fs::path mid = copy("truncated-mid-page.db");
    fs::resize_file(mid, page + 1000);
    check(mid, damaged);
    const fs::path half = copy("truncated-half.db");
    fs::resize_file(half, (size / page / 2) * page);
    check(half, damaged);
  }
  {  // Not SQLite at all.
    const fs::path text = dir.path() / "notes.db";
    std::ofstream(text) << "# strokelab jobs\nthis is a text file that happens to end in .db\n";
    ++tried;
    check(text, damaged);
  }
  std::printf("%d of %d damaged files refused; %.1f s\n", refused, tried, SecondsSince(test_start));
}

TEST(DamagedDatabase, LockedFileWaitedForThenRefused) {
  ScratchDir dir("strokelab-fault-lock");
  const fs::path db = MakeGoodDatabase(dir.path());
  {
    Db holder(db);
    holder.Query("BEGIN EXCLUSIVE");
    const std::string log = ExpectRefused(dir.path(), db, {"locked"});
    std::printf("  locked: %s", log.c_str());
    holder.Query("ROLLBACK");
  }
  // Free again: starts, with the job still there.
  Server server = StartServer(dir.path(), "serve-free", {"--workers", "1", "--db", db.string(), "--quiet"});
  EXPECT_EQ(GetJson(*Client(server), "/v1/jobs/1").at("status"), "succeeded");
  server.child->Signal(SIGTERM);
  EXPECT_EQ(server.child->WaitExit(20), 0) << server.child->Log();
}

TEST(DamagedDatabase, StopWhileWaitingForALock) {
  ScratchDir dir("strokelab-fault-lockstop");
  const fs::path db = MakeGoodDatabase(dir.path());
  Db holder(db);
  holder.Query("BEGIN EXCLUSIVE");
  Child server({STROKELAB_BINARY, "serve", "--port", "0", "--workers", "1", "--db", db.string(), "--quiet"},
               dir.path() / "serve-waiting.log");
  // Once it has the file open it is past installing its signal handlers and waits on the lock. Stop
  // it, free the lock: it goes on starting, then must see the stop and exit.
  const auto start = Clock::now();
  for (bool open = false; !open;) {
    for (const auto& fd : fs::directory_iterator("/proc/" + std::to_string(server.pid()) + "/fd")) {
      std::error_code ec;
      open = open || fs::read_symlink(fd.path(), ec) == db;
    }
    ASSERT_FALSE(server.Poll()) << server.Log();
    ASSERT_LT(SecondsSince(start), 20) << "the server never opened " << db;
    SleepMs(5);
  }
  SleepMs(100);
  server.Signal(SIGTERM);
  holder.Query("ROLLBACK");
  const int code = server.WaitExit(30);
  EXPECT_EQ(code, 0) << server.Log();
}

}  // namespace
}  // namespace strokelab::test_fault
