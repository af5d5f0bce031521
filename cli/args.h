// A small command-line parser: `--name value`, `--name=value` and boolean `--flag`, each command
// declaring what it accepts so that an unknown or malformed flag is a one-line error naming it.
#pragma once

#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace strokelab::cli {

class Args {
 public:
  // `valued`: flags that take a value; `booleans`: flags that do not; `repeatable` values of a
  // valued flag collect in order (e.g. --set). Throws InputError on an unknown flag.
  Args(const std::vector<std::string>& argv, std::set<std::string> valued, std::set<std::string> booleans,
       std::set<std::string> repeatable = {});

  bool Has(const std::string& flag) const;
  std::optional<std::string> Get(const std::string& flag) const;
  std::string GetOr(const std::string& flag, const std::string& fallback) const;
  std::vector<std::string> GetAll(const std::string& flag) const;
  // A number; throws InputError("--flag", ...) if it does not parse or is not finite.
  double Number(const std::string& flag, double fallback) const;
  int Integer(const std::string& flag, int fallback) const;
  // "A:B" -> {A, B}, a single value "V" -> {V, V}; {from, to} when the flag is absent. Errors name it.
  std::pair<double, double> Range(const std::string& flag, double from, double to) const;
  const std::vector<std::string>& Positional() const { return positional_; }

 private:
  std::map<std::string, std::vector<std::string>> values_;
  std::set<std::string> booleans_seen_;
  std::vector<std::string> positional_;
};

}  // namespace strokelab::cli
