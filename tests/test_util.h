// Shared test helpers: relative comparisons with named tolerances, Eigen comparisons, IsValid as text.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <numbers>
#include <optional>
#include <string>

#include "strokelab/base/errors.h"

namespace strokelab::testing {

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

}  // namespace strokelab::testing

#define EXPECT_REL_NEAR(actual, expected, rel) \
  EXPECT_TRUE(::strokelab::testing::NearRelative((actual), (expected), (rel)))
#define ASSERT_REL_NEAR(actual, expected, rel) \
  ASSERT_TRUE(::strokelab::testing::NearRelative((actual), (expected), (rel)))
