// The kinds of error, which callers tell apart: bad input (InputError, naming the field), a failed
// numerical method (NumericalError), work stopped on request (Cancelled), and a broken internal
// invariant (BrokenInvariant: a bug, never the user's input).
#pragma once

#include <optional>
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

// What is wrong with a value: the field (a name, a CLI flag, a JSON pointer) and why. The one
// validation convention: every model, drive and options type has
//   std::optional<FieldError> IsValid() const;   // nothing, or its first wrong field
// and Validate(value) throws that as an InputError. Callers that speak another language of names
// (a job's JSON pointers, the CLI's flags) map `field` instead of parsing a message.
struct FieldError {
  std::string field, message;
};

template <class T>
void Validate(const T& value) {
  if (std::optional<FieldError> error = value.IsValid()) throw InputError(error->field, error->message);
}

// A numerical method failed (solver error, non-finite state). Carries the solver's own words.
class NumericalError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A computation spent its work budget (steps, switches, iterations) without finishing: the model's
// time scales are beyond what the engine resolves. The service counts these per task (a task that
// spent its budget twice is not leased again).
class WorkBudgetSpent : public NumericalError {
 public:
  using NumericalError::NumericalError;
};

// Work stopped because its caller asked (a cancelled job, an interrupted command).
struct Cancelled : std::exception {
  const char* what() const noexcept override { return "cancelled"; }
};

// Thrown by BrokenInvariant in release builds; the service answers it 500 with a logged incident id.
class InvariantError : public std::logic_error {
 public:
  using std::logic_error::logic_error;
};

// A broken internal invariant. Debug builds (NDEBUG not defined, as in the sanitizer builds) print
// `what` and abort where it broke, as assert does; release builds throw InvariantError so that one
// bad request does not take the service down.
[[noreturn]] void BrokenInvariant(const std::string& what);

}  // namespace strokelab
