// The comparison behind `strokelab regress` on hand-made tables (no job is run): the tolerance
// rules and their overrides, null and non-finite values, row matching (missing, extra, reordered
// and repeated keys), the worst deviation, and the baseline file format.
#include "regression.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include "strokelab/base/errors.h"

namespace strokelab::cli::regression {
namespace {

using nlohmann::json;
using ::testing::HasSubstr;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

bool Passes(const std::string& field, double baseline, double now, const std::string& table = "points") {
  return CompareValue(baseline, now, Tolerances::Defaults().For(table, field)).pass;
}

// An InputError from Apply, with its field (JSON pointer) and message.
InputError ApplyError(const json& overrides) {
  Tolerances t = Tolerances::Defaults();
  try {
    t.Apply(overrides);
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "no error for " << overrides.dump();
  return InputError("", "");
}

json Point(double f, double v, const std::string& branch, double h_re = 1.0) {
  return {{"frequency_hz", f}, {"amplitude_v", v}, {"branch", branch}, {"h_re_n_per_v", h_re}, {"period", 1}};
}

TEST(RegressionToleranceTest, DefaultsByField) {
  // Grid coordinates are exact: one ulp is a change.
  EXPECT_TRUE(Passes("frequency_hz", 5.306040000000001, 5.306040000000001));
  EXPECT_FALSE(Passes("frequency_hz", 5.0, std::nextafter(5.0, 6.0)));
  EXPECT_FALSE(Passes("amplitude_v", 0.3, 0.30000000000000004));
  // Harmonics: relative 1e-9 ...
  EXPECT_TRUE(Passes("h_re_n_per_v", 2.0, 2.0 * (1 + 0.9e-9)));
  EXPECT_FALSE(Passes("h_re_n_per_v", 2.0, 2.0 * (1 + 1.1e-9)));
  EXPECT_FALSE(Passes("first_harmonic_force_n", 0.0774, 0.0774 * (1 + 2e-9)));
  // ... with an absolute floor of 1e-12 near zero.
  EXPECT_TRUE(Passes("h_im_n_per_v", 0.0, 0.9e-12));
  EXPECT_FALSE(Passes("h_im_n_per_v", 0.0, 1.1e-12));
  // Displacements: absolute 1e-12 m whatever their size.
  EXPECT_TRUE(Passes("min_displacement_m", -1e-3, -1e-3 + 0.9e-12));
  EXPECT_FALSE(Passes("max_displacement_m", 1.4e-3, 1.4e-3 + 1.1e-12));
  // Located thresholds and jump bounds: relative 1e-8 and 1e-7.
  EXPECT_TRUE(Passes("grazing_amplitude_v", 0.3, 0.3 * (1 + 0.9e-8), "thresholds"));
  EXPECT_FALSE(Passes("lowest_contact_amplitude_v", 0.3, 0.3 * (1 + 1.1e-8), "thresholds"));
  EXPECT_TRUE(Passes("bistable_from_hz", 12.0, 12.0 * (1 + 0.9e-7), "jumps"));
  EXPECT_FALSE(Passes("bistable_to_hz", 12.0, 12.0 * (1 + 1.1e-7), "jumps"));
  // Counts are exact; wall times are ignored.
  EXPECT_FALSE(Passes("contacts_per_period", 1.0, 2.0));
  EXPECT_TRUE(Passes("wall_time_s", 0.1, 100.0));
  // A field without a default: relative 1e-9, no floor.
  EXPECT_TRUE(Passes("some_new_field", 3.0, 3.0 * (1 + 0.9e-9)));
  EXPECT_FALSE(Passes("some_new_field", 0.0, 1e-300));
}

TEST(RegressionToleranceTest, NonNumbersCompareExactly) {
  const Tolerance numeric = Tolerance::Numeric(1.0, 1.0);
  EXPECT_TRUE(CompareValue("up", "up", numeric).pass);
  EXPECT_FALSE(CompareValue("up", "down", numeric).pass);
  EXPECT_FALSE(CompareValue(true, false, numeric).pass);
  // period: an integer, or "aperiodic".
  EXPECT_TRUE(CompareValue(2, 2, Tolerance::Exact()).pass);
  EXPECT_FALSE(CompareValue(1, "aperiodic", numeric).pass);
  EXPECT_FALSE(CompareValue(true, 1, numeric).pass);
  // An integer and the same value as a double are the same number.
  EXPECT_TRUE(CompareValue(13, 13.0, Tolerance::Exact()).pass);
}

TEST(RegressionToleranceTest, PhasesWrapAroundTwoPi) {
  EXPECT_TRUE(Passes("first_harmonic_phase_rad", std::numbers::pi - 1e-10, -std::numbers::pi + 1e-10));
  EXPECT_FALSE(Passes("first_harmonic_phase_rad", std::numbers::pi - 1e-8, -std::numbers::pi + 1e-8));
  const ValueCheck c = CompareValue(3.0, 3.0 + 2 * std::numbers::pi, Tolerance::Numeric(0, 1e-9, true));
  EXPECT_TRUE(c.pass);
  EXPECT_LT(c.absolute, 1e-12);
}

TEST(RegressionToleranceTest, NullAndNonFinite) {
  const Tolerance t = Tolerance::Numeric(1e-9, 1e-12);
  // null (what a non-finite number is written as) equals null, and a NaN or inf in memory is null.
  EXPECT_TRUE(CompareValue(nullptr, nullptr, t).pass);
  EXPECT_TRUE(CompareValue(nullptr, kNaN, t).pass);
  EXPECT_TRUE(CompareValue(kInf, nullptr, t).pass);
  EXPECT_TRUE(CompareValue(kNaN, kNaN, t).pass);
  // null against a number is a regression either way, with an infinite deviation.
  const ValueCheck appeared = CompareValue(nullptr, 0.3, t);
  EXPECT_FALSE(appeared.pass);
  EXPECT_TRUE(std::isinf(appeared.absolute));
  EXPECT_TRUE(std::isinf(appeared.used));
  EXPECT_FALSE(CompareValue(0.3, nullptr, t).pass);
  EXPECT_FALSE(CompareValue(0.3, kNaN, t).pass);
  // An ignored field passes whatever it holds.
  EXPECT_TRUE(CompareValue(0.3, nullptr, Tolerance::Ignore()).pass);
  // Normalized turns non-finite numbers into null, as the JSON written.
  const json n = Normalized({{"a", kNaN}, {"b", -kInf}, {"c", 1.5}});
  EXPECT_TRUE(n["a"].is_null());
  EXPECT_TRUE(n["b"].is_null());
  EXPECT_EQ(n["c"], 1.5);
}

TEST(RegressionToleranceTest, ShareOfTheToleranceUsed) {
  const ValueCheck c = CompareValue(2.0, 2.0 + 1e-9, Tolerance::Numeric(1e-9, 0.0));
  EXPECT_TRUE(c.pass);
  EXPECT_NEAR(c.relative, 5e-10, 1e-15);
  EXPECT_NEAR(c.used, 0.5, 1e-6);
  const ValueCheck exact = CompareValue(2.0, 2.0 + 1e-9, Tolerance::Exact());
  EXPECT_FALSE(exact.pass);
  EXPECT_TRUE(std::isinf(exact.used));
  const ValueCheck from_zero = CompareValue(0.0, 1e-13, Tolerance::Numeric(1e-9, 1e-12));
  EXPECT_TRUE(from_zero.pass);
  EXPECT_TRUE(std::isinf(from_zero.relative));
  EXPECT_NEAR(from_zero.used, 0.1, 1e-9);
}

TEST(RegressionToleranceTest, OverridesReplaceTheDefaultRule) {
  Tolerances t = Tolerances::Defaults();
  t.Apply({{"first_harmonic_force_n", {{"relative", 1e-6}}},
           {"points.peak_force_n", {{"absolute", 0.5}}},
           {"max_multiplier", "ignore"},
           {"h_re_n_per_v", {{"exact", true}}},
           {"first_harmonic_phase_rad", {{"absolute", 1e-3}}}});
  const Tolerance force = t.For("records", "first_harmonic_force_n");
  EXPECT_EQ(force.kind, Tolerance::Kind::kNumeric);
  EXPECT_EQ(force.relative, 1e-6);
  EXPECT_EQ(force.absolute, 0.0);  // the default's floor is replaced too
  EXPECT_TRUE(CompareValue(0.2, 0.2 * (1 + 0.9e-6), force).pass);
  // TABLE.FIELD applies to that table only.
  EXPECT_EQ(t.For("points", "peak_force_n").absolute, 0.5);
  EXPECT_EQ(t.For("records", "peak_force_n").absolute, 1e-12);
  EXPECT_EQ(t.For("points", "max_multiplier").kind, Tolerance::Kind::kIgnore);
  EXPECT_EQ(t.For("points", "h_re_n_per_v").kind, Tolerance::Kind::kExact);
  // A phase stays an angle under a new tolerance.
  EXPECT_TRUE(t.For("points", "first_harmonic_phase_rad").angle);
  // "exact" and "ignore" as strings.
  t.Apply({{"contacts", "ignore"}, {"records.mean_contact_ms", "exact"}});
  EXPECT_EQ(t.For("records", "contacts").kind, Tolerance::Kind::kIgnore);
  EXPECT_EQ(t.For("records", "mean_contact_ms").kind, Tolerance::Kind::kExact);
}

TEST(RegressionToleranceTest, BadOverridesNameTheirPointer) {
  struct Case {
    json overrides;
    std::string field, message;
  };
  const Case cases[] = {
      {json::array(), "/tolerances", "must be an object"},
      {{{"first_harmonic_forc_n", {{"relative", 1e-6}}}}, "/tolerances/first_harmonic_forc_n", "is not a result field"},
      {{{"pointz.h_re_n_per_v_n_per_v", "exact"}}, "/tolerances/pointz.h_re_n_per_v_n_per_v", "unknown table 'pointz'"},
      {{{"h_re_n_per_v", {{"relative", -1}}}}, "/tolerances/h_re_n_per_v/relative", "must be a number >= 0"},
      {{{"h_re_n_per_v", {{"relative", "1e-6"}}}}, "/tolerances/h_re_n_per_v/relative", "must be a number >= 0"},
      {{{"h_re_n_per_v", {{"rel", 1e-6}}}}, "/tolerances/h_re_n_per_v/rel", "unknown key (known: relative, absolute, exact, ignore)"},
      {{{"h_re_n_per_v", json::object()}}, "/tolerances/h_re_n_per_v", "give relative and/or absolute"},
      {{{"h_re_n_per_v", "loose"}}, "/tolerances/h_re_n_per_v", "expected \"exact\", \"ignore\""},
      {{{"h_re_n_per_v", 1e-6}}, "/tolerances/h_re_n_per_v", "expected \"exact\", \"ignore\""},
      {{{"h_re_n_per_v", {{"exact", false}}}}, "/tolerances/h_re_n_per_v/exact", "must be true"},
      {{{"h_re_n_per_v", {{"ignore", true}, {"relative", 1}}}}, "/tolerances/h_re_n_per_v/ignore", "cannot be combined"},
      {{{"a/b", "exact"}}, "/tolerances/a~1b", "is not a result field"},
  };
  for (const Case& c : cases) {
    const InputError e = ApplyError(c.overrides);
    EXPECT_EQ(e.field(), c.field) << c.overrides.dump();
    EXPECT_THAT(e.bare_message(), HasSubstr(c.message)) << c.overrides.dump();
  }
  // A bad entry leaves the rules as they were.
  Tolerances t = Tolerances::Defaults();
  EXPECT_THROW(t.Apply({{"h_re_n_per_v", "exact"}, {"h_im_n_per_v", "loose"}}), InputError);
  EXPECT_EQ(t.For("points", "h_re_n_per_v").kind, Tolerance::Kind::kNumeric);
}

TEST(RegressionCompareTest, IdenticalTablesPass) {
  const json tables = {{"points", {Point(5, 0.1, "up"), Point(5, 0.1, "down"), Point(6, 0.1, "up")}},
                       {"thresholds", {{{"frequency_hz", 5.0}, {"grazing_amplitude_v", nullptr}}}}};
  const Comparison c = CompareTables(tables, tables, Tolerances::Defaults());
  EXPECT_TRUE(c.Passed());
  EXPECT_EQ(c.rows_compared, 4u);
  EXPECT_FALSE(c.worst.has_value());
}

TEST(RegressionCompareTest, RowsMatchByKeyNotPosition) {
  const json baseline = {{"points", {Point(5, 0.1, "up"), Point(5, 0.1, "down"), Point(6, 0.1, "up")}}};
  const json now = {{"points", {Point(6, 0.1, "up"), Point(5, 0.1, "down"), Point(5, 0.1, "up")}}};
  const Comparison c = CompareTables(baseline, now, Tolerances::Defaults());
  EXPECT_TRUE(c.Passed()) << ::testing::PrintToString(c.regressions);
  EXPECT_EQ(c.rows_compared, 3u);
}

TEST(RegressionCompareTest, EqualKeysMatchInOrder) {
  // Two jump intervals at one amplitude: the first matches the first, the second the second.
  const json a = {{"amplitude_v", 0.4}, {"bistable_from_hz", 10.0}, {"bistable_to_hz", 11.0}};
  const json b = {{"amplitude_v", 0.4}, {"bistable_from_hz", 20.0}, {"bistable_to_hz", 21.0}};
  const Comparison same = CompareTables({{"jumps", {a, b}}}, {{"jumps", {a, b}}}, Tolerances::Defaults());
  EXPECT_TRUE(same.Passed());
  const Comparison swapped = CompareTables({{"jumps", {a, b}}}, {{"jumps", {b, a}}}, Tolerances::Defaults());
  ASSERT_FALSE(swapped.Passed());
  EXPECT_THAT(swapped.regressions[0], HasSubstr("jumps[V=0.4 V].bistable_from_hz: 20.0 now, 10.0 in the baseline"));
  EXPECT_THAT(swapped.regressions.back(), HasSubstr("jumps[V=0.4 V, #2].bistable_to_hz"));
}

TEST(RegressionCompareTest, MissingAndExtraRowsAndTables) {
  const json baseline = {{"points", {Point(5, 0.1, "up"), Point(5, 0.1, "unstable"), Point(6, 0.1, "up")}},
                         {"jumps", {{{"amplitude_v", 0.1}, {"bistable_from_hz", 5.5}}}}};
  const json now = {{"points", {Point(5, 0.1, "up"), Point(6, 0.1, "up"), Point(7, 0.1, "up")}}};
  const Comparison c = CompareTables(baseline, now, Tolerances::Defaults());
  EXPECT_EQ(c.rows_compared, 2u);
  ASSERT_EQ(c.regressions.size(), 3u) << ::testing::PrintToString(c.regressions);
  EXPECT_EQ(c.regressions[0], "jumps[V=0.1 V]: missing row (in the baseline, not in the results)");
  EXPECT_EQ(c.regressions[1], "points[f=5 Hz, V=0.1 V, unstable]: missing row (in the baseline, not in the results)");
  EXPECT_EQ(c.regressions[2], "points[f=7 Hz, V=0.1 V, up]: extra row (in the results, not in the baseline)");
  // A row with a third equal key is extra too.
  const Comparison repeated =
      CompareTables({{"points", {Point(5, 0.1, "up")}}}, {{"points", {Point(5, 0.1, "up"), Point(5, 0.1, "up")}}},
                    Tolerances::Defaults());
  ASSERT_EQ(repeated.regressions.size(), 1u);
  EXPECT_THAT(repeated.regressions[0], HasSubstr("points[f=5 Hz, V=0.1 V, up, #2]: extra row"));
  // A grid point moved by one ulp no longer matches: missing and extra.
  const Comparison moved = CompareTables({{"points", {Point(5, 0.1, "up")}}},
                                         {{"points", {Point(std::nextafter(5.0, 6.0), 0.1, "up")}}}, Tolerances::Defaults());
  EXPECT_EQ(moved.regressions.size(), 2u);
}

TEST(RegressionCompareTest, FieldsPresentOnOneSideOnly) {
  json old_row = Point(5, 0.1, "up");
  json new_row = old_row;
  new_row.erase("h_re_n_per_v");
  new_row["max_multiplier"] = 0.5;
  new_row["wall_time_s"] = 0.01;  // ignored fields may come and go
  const Comparison c = CompareTables({{"points", {old_row}}}, {{"points", {new_row}}}, Tolerances::Defaults());
  ASSERT_EQ(c.regressions.size(), 2u) << ::testing::PrintToString(c.regressions);
  EXPECT_EQ(c.regressions[0], "points[f=5 Hz, V=0.1 V, up].h_re_n_per_v: missing now (baseline 1.0)");
  EXPECT_EQ(c.regressions[1], "points[f=5 Hz, V=0.1 V, up].max_multiplier: new field, not in the baseline (now 0.5)");
}

TEST(RegressionCompareTest, RegressionLinesAndTheWorstValue) {
  const json baseline = {{"points", {Point(5, 0.1, "up", 2.0), Point(6, 0.1, "up", 3.0), Point(7, 0.1, "up", 4.0)}}};
  const json now = {{"points", {Point(5, 0.1, "up", 2.0 * (1 + 2e-10)), Point(6, 0.1, "up", 3.0 * (1 + 6e-10)),
                                Point(7, 0.1, "up", 4.0)}}};
  const Comparison pass = CompareTables(baseline, now, Tolerances::Defaults());
  EXPECT_TRUE(pass.Passed());
  ASSERT_TRUE(pass.worst.has_value());
  EXPECT_EQ(pass.worst->where, "points[f=6 Hz, V=0.1 V, up].h_re_n_per_v");
  EXPECT_NEAR(pass.worst->check.relative, 6e-10, 1e-15);
  EXPECT_NEAR(pass.worst->check.used, 0.6, 1e-5);

  json broken = now;
  broken["points"][2]["h_re_n_per_v"] = 4.0 * (1 + 1e-6);
  broken["points"][0]["period"] = "aperiodic";
  const Comparison fail = CompareTables(baseline, broken, Tolerances::Defaults());
  ASSERT_EQ(fail.regressions.size(), 2u) << ::testing::PrintToString(fail.regressions);
  EXPECT_EQ(fail.regressions[0], "points[f=5 Hz, V=0.1 V, up].period: \"aperiodic\" now, 1 in the baseline (exact)");
  EXPECT_THAT(fail.regressions[1], HasSubstr("points[f=7 Hz, V=0.1 V, up].h_re_n_per_v: 4.000004 now, 4.0 in the baseline"));
  EXPECT_THAT(fail.regressions[1], HasSubstr("relative deviation 1e-06 beyond tolerance relative 1e-09, absolute 1e-12"));
  // The worst: a mismatch (infinitely beyond) before a value 1000 x its tolerance.
  ASSERT_TRUE(fail.worst.has_value());
  EXPECT_EQ(fail.worst->where, "points[f=5 Hz, V=0.1 V, up].period");

  // Null where a number was.
  json lost = baseline;
  lost["points"][1]["h_re_n_per_v"] = nullptr;
  const Comparison nulls = CompareTables(baseline, lost, Tolerances::Defaults());
  ASSERT_EQ(nulls.regressions.size(), 1u);
  EXPECT_THAT(nulls.regressions[0], HasSubstr("points[f=6 Hz, V=0.1 V, up].h_re_n_per_v: null now, 3.0 in the baseline"));
}

TEST(RegressionCompareTest, MalformedTablesAreInputErrors) {
  EXPECT_THROW(CompareTables({{"points", {1, 2}}}, json::object(), Tolerances::Defaults()), InputError);
  EXPECT_THROW(CompareTables({{"points", json::object()}}, json::object(), Tolerances::Defaults()), InputError);
  EXPECT_THROW(CompareTables(json::array(), json::object(), Tolerances::Defaults()), InputError);
}

TEST(RegressionBaselineTest, FormatRoundTripsOneRowALine) {
  const json job = {{"kind", "simulate"}, {"model", "paper"}, {"frequency_hz", 8}, {"amplitude_v", 0.5}};
  const json tables = Normalized({{"records", {{{"frequency_hz", 8.0}, {"peak_force_n", 15.0513854537499},
                                               {"mean_contact_ms", kNaN}, {"h", 0.1 + 0.2}}}},
                                  {"points", json::array()}});
  const std::string text = FormatBaseline(job, "strokelab-9.9.9", tables);
  const json parsed = json::parse(text);
  EXPECT_EQ(parsed["job"], job);
  EXPECT_EQ(parsed["code_version"], "strokelab-9.9.9");
  EXPECT_EQ(parsed["tables"], tables);
  EXPECT_EQ(parsed["tables"]["records"][0]["h"].get<double>(), 0.1 + 0.2);  // doubles survive exactly
  EXPECT_TRUE(parsed["tables"]["records"][0]["mean_contact_ms"].is_null());
  EXPECT_THAT(text, HasSubstr("\n      {\"frequency_hz\":8.0,"));
  EXPECT_NO_THROW(CheckBaseline(parsed, "b.json"));
  EXPECT_TRUE(CompareTables(parsed["tables"], tables, Tolerances::Defaults()).Passed());
  EXPECT_TRUE(json::accept(FormatBaseline(job, "v", json::object())));
}

TEST(RegressionBaselineTest, BadBaselinesNameTheFile) {
  const auto message = [](const json& baseline) -> std::string {
    try {
      CheckBaseline(baseline, "base/x.json");
    } catch (const InputError& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_THAT(message(json::array()), HasSubstr("base/x.json: a baseline must be a JSON object"));
  EXPECT_THAT(message({{"job", json::object()}}), HasSubstr("base/x.json: no \"tables\""));
  EXPECT_THAT(message({{"tables", json::object()}}), HasSubstr("base/x.json: no \"job\" object"));
  EXPECT_THAT(message({{"job", json::object()}, {"tables", {{"points", {1}}}}}),
              HasSubstr("base/x.json: /tables/points/0: must be an object"));
}

}  // namespace
}  // namespace strokelab::cli::regression
