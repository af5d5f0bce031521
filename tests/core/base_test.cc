// core's base stage: the one thread pool (ParallelFor), the kinds of error, JSON numbers, the
// Illinois root bracket.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "strokelab/base/errors.h"
#include "strokelab/base/illinois.h"
#include "strokelab/base/json_number.h"
#include "strokelab/base/parallel_for.h"

namespace strokelab {
namespace {

TEST(ParallelFor, RunsEveryItemOnceOnAnyThreadCount) {
  for (size_t threads : {1u, 2u, 7u, 0u}) {
    std::vector<std::atomic<int>> runs(1000);
    ParallelFor(runs.size(), [&](size_t i) { ++runs[i]; }, threads);
    for (size_t i = 0; i < runs.size(); ++i) ASSERT_EQ(runs[i].load(), 1) << "item " << i << ", " << threads << " threads";
  }
  ParallelFor(0, [](size_t) { FAIL() << "no items, no calls"; });
}

TEST(ParallelFor, RethrowsTheLowestFailedItemAndStartsNoneAfterAFailure) {
  for (size_t threads : {1u, 2u, 4u}) {
    std::atomic<size_t> started{0};
    try {
      ParallelFor(
          10000,
          [&](size_t i) {
            ++started;
            if (i == 30 || i == 31) throw std::runtime_error("item " + std::to_string(i));
          },
          threads);
      FAIL() << "no exception";
    } catch (const std::runtime_error& e) {
      EXPECT_STREQ(e.what(), "item 30") << threads << " threads";
    }
    // Once an item has failed no further one starts: each thread may have started one more.
    EXPECT_LE(started.load(), 32 + threads) << threads << " threads";
  }
}

TEST(ParallelFor, ACancelFlagEndsTheLoopWithCancelled) {
  std::atomic<bool> cancel{false};
  std::atomic<size_t> started{0};
  EXPECT_THROW(ParallelFor(
                   1000,
                   [&](size_t i) {
                     ++started;
                     if (i == 10) cancel = true;
                   },
                   1, &cancel),
               Cancelled);
  EXPECT_EQ(started.load(), 11u) << "one thread: items 0 .. 10, then the flag is seen";
}

TEST(Errors, AnInputErrorKeepsItsFieldApartFromItsMessage) {
  const InputError e("/grid/amplitude_v/to", "must be > from");
  EXPECT_EQ(e.field(), "/grid/amplitude_v/to");
  EXPECT_EQ(e.bare_message(), "must be > from");
  EXPECT_STREQ(e.what(), "/grid/amplitude_v/to: must be > from");
}

// Debug builds (the sanitizer stages) stop at a broken invariant; release builds throw, so that the
// service can answer 500 and go on.
TEST(Errors, ABrokenInvariantAbortsInDebugAndThrowsInRelease) {
#ifdef NDEBUG
  EXPECT_THROW(BrokenInvariant("two plus two is five"), InvariantError);
#else
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_DEATH(BrokenInvariant("two plus two is five"), "broken invariant: two plus two is five");
#endif
}

TEST(JsonNumber, NonFiniteIsNull) {
  EXPECT_EQ(JsonNumber(0.25), nlohmann::json(0.25));
  EXPECT_TRUE(JsonNumber(std::nan("")).is_null());
  EXPECT_TRUE(JsonNumber(-std::numeric_limits<double>::infinity()).is_null());
}

// Evaluations of g until the bracket is 1e-12 wide (or an exact root), and the root found.
template <class G>
std::pair<int, double> SolveByIllinois(G g, double a, double b) {
  IllinoisBracket bracket{a, b, g(a), g(b)};
  int evaluations = 0;
  while (bracket.Width() > 1e-12 && evaluations < 200) {
    const double x = bracket.Next();
    const double gx = g(x);
    ++evaluations;
    bracket.Update(x, gx);
    if (gx == 0.0) break;
  }
  return {evaluations, bracket.gb == 0.0 ? bracket.b : 0.5 * (bracket.a + bracket.b)};
}

TEST(IllinoisBracket, ConvergesSuperlinearlyWhereRegulaFalsiKeepsOneEnd) {
  // x^3 - 2 on [0, 2]: convex, so plain regula falsi keeps the end at 2 and crawls (hundreds of
  // evaluations to 1e-12), and halving the kept end on every step, not only when it is kept twice,
  // is linear (~40). Illinois takes about ten.
  const auto [evaluations, root] = SolveByIllinois([](double x) { return x * x * x - 2.0; }, 0.0, 2.0);
  EXPECT_NEAR(root, std::cbrt(2.0), 1e-12);
  EXPECT_LE(evaluations, 15);
}

TEST(IllinoisBracket, AnExactZeroAtOneEndKeepsTheRootInside) {
  // After g(b) = 0 exactly, a point with a's sign must replace a, not b: judged against b's zero, it
  // would move b away and the bracket would close on a, far from the root (seen: a grazing amplitude
  // located at half its value).
  IllinoisBracket bracket{0.0, 1.0, -1.0, 1.0};
  bracket.Update(0.5, 0.0);
  EXPECT_EQ(bracket.b, 0.5);
  bracket.Update(0.25, -0.5);
  EXPECT_EQ(bracket.a, 0.25);
  EXPECT_EQ(bracket.b, 0.5);
  // A linear g hits its root at the first secant point.
  const auto [evaluations, root] = SolveByIllinois([](double x) { return 0.3 - x; }, 0.0, 1.0);
  EXPECT_EQ(evaluations, 1);
  EXPECT_DOUBLE_EQ(root, 0.3);
}

}  // namespace
}  // namespace strokelab
