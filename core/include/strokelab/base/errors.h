// Errors that end a request: bad user input. Internal invariants use assert, never this.
#pragma once

#include <stdexcept>
#include <string>

namespace strokelab {

// Bad input from a user: names the offending field (a CLI flag, a JSON pointer, a file:line).
class InputError : public std::runtime_error {
 public:
  InputError(std::string field, const std::string& message)
      : std::runtime_error(field.empty() ? message : field + ": " + message),
        field_(std::move(field)),
        message_(message) {}
  const std::string& field() const { return field_; }
  // The message without the field prefix.
  const std::string& bare_message() const { return message_; }

 private:
  std::string field_;
  std::string message_;
};

// A numerical method failed (solver error, non-finite state). Carries the solver's own words.
class NumericalError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Work stopped because its caller asked (a cancelled job, an interrupted command).
struct Cancelled : std::exception {
  const char* what() const noexcept override { return "cancelled"; }
};

}  // namespace strokelab
