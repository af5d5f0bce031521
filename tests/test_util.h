// Shared test helpers: relative comparisons with named tolerances, Eigen comparisons, IsValid as text,
// option tables.
#pragma once

#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <complex>
#include <filesystem>
#include <numbers>
#include <optional>
#include <string>
#include <variant>

#include "strokelab/base/errors.h"

namespace strokelab::testing {

// An empty directory of its own for the running test: TempDir/PREFIX_PID_TESTNAME, emptied if a
// run before left it.
inline std::filesystem::path FreshTestDir(const std::string& prefix) {
  const std::filesystem::path dir =
      std::filesystem::path(::testing::TempDir()) /
      (prefix + "_" + std::to_string(::getpid()) + "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kFs = 51200.0;  // the paper's sampling rate [Hz]
// An estimate passes when it lies within this many of its standard errors of the truth.
inline constexpr double kSigmaBound = 3.0;

// |actual - expected| <= rel * |expected|, printed with both values and the relative error.
inline ::testing::AssertionResult NearRelative(double actual, double expected, double rel) {
  const double err = std::abs(actual - expected) / std::abs(expected);
  if (std::isfinite(err) && err <= rel) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "actual " << actual << " vs expected " << expected
                                       << ": relative error " << err << " > " << rel;
}

inline ::testing::AssertionResult NearRelative(std::complex<double> actual, std::complex<double> expected,
                                               double rel) {
  const double err = std::abs(actual - expected) / std::abs(expected);
  if (std::isfinite(err) && err <= rel) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "actual " << actual << " vs expected " << expected
                                       << ": relative error " << err << " > " << rel;
}

// What IsValid says of an options or model value: "field: message", or "" when it is valid.
template <class T>
std::string IsValidText(const T& value) {
  const std::optional<FieldError> error = value.IsValid();
  return error ? error->field + ": " + error->message : "";
}

// An option table (OptionInfo, fit.h) as "field job_name flag" entries joined by "; " (flag "-" for
// none, "(clears)" after a switch that clears its bool): pins every name of the table at once.
template <class Table>
std::string OptionNames(const Table& table) {
  std::string out;
  for (const auto& info : table)
    out += std::string(out.empty() ? "" : "; ") + info.field + " " + info.job_name + " " +
           (info.flag ? info.flag : "-") + (info.flag_clears ? " (clears)" : "");
  return out;
}

// Each number of an option table set to a wrong value in turn (-1000 for an int, NaN for a double;
// a bool is never wrong): IsValid must name the table's field.
template <class Options, class Table>
void ExpectTableFieldsAreIsValidFields(const Table& table) {
  for (const auto& info : table) {
    SCOPED_TRACE(info.field);
    Options options;
    if (const auto* member = std::get_if<int Options::*>(&info.member))
      options.**member = -1000;
    else if (const auto* member = std::get_if<double Options::*>(&info.member))
      options.**member = std::nan("");
    else
      continue;
    const std::optional<FieldError> error = options.IsValid();
    ASSERT_TRUE(error);
    EXPECT_EQ(error->field, info.field);
  }
}

}  // namespace strokelab::testing

#define EXPECT_REL_NEAR(actual, expected, rel) \
  EXPECT_TRUE(::strokelab::testing::NearRelative((actual), (expected), (rel)))
#define ASSERT_REL_NEAR(actual, expected, rel) \
  ASSERT_TRUE(::strokelab::testing::NearRelative((actual), (expected), (rel)))
