#include "args.h"

#include <cmath>

#include "strokelab/base/errors.h"
#include "strokelab/base/parse.h"

namespace strokelab::cli {

Args::Args(const std::vector<std::string>& argv, std::set<std::string> valued, std::set<std::string> booleans,
           std::set<std::string> repeatable) {
  for (size_t i = 0; i < argv.size(); ++i) {
    const std::string& arg = argv[i];
    if (arg.rfind("--", 0) != 0) {
      positional_.push_back(arg);
      continue;
    }
    std::string name = arg;
    std::optional<std::string> inline_value;
    if (const size_t eq = arg.find('='); eq != std::string::npos) {
      name = arg.substr(0, eq);
      inline_value = arg.substr(eq + 1);
    }
    if (booleans.count(name)) {
      if (inline_value) throw InputError(name, "takes no value");
      booleans_seen_.insert(name);
      continue;
    }
    if (!valued.count(name)) throw InputError(name, "unknown option (see --help)");
    std::string value;
    if (inline_value) {
      value = *inline_value;
    } else {
      if (i + 1 >= argv.size()) throw InputError(name, "needs a value");
      value = argv[++i];
    }
    auto& slot = values_[name];
    if (!slot.empty() && !repeatable.count(name)) throw InputError(name, "given more than once");
    slot.push_back(value);
  }
}

bool Args::Has(const std::string& flag) const { return booleans_seen_.count(flag) || values_.count(flag); }

std::optional<std::string> Args::Get(const std::string& flag) const {
  auto it = values_.find(flag);
  if (it == values_.end()) return std::nullopt;
  return it->second.back();
}

std::string Args::GetOr(const std::string& flag, const std::string& fallback) const {
  return Get(flag).value_or(fallback);
}

std::vector<std::string> Args::GetAll(const std::string& flag) const {
  auto it = values_.find(flag);
  return it == values_.end() ? std::vector<std::string>{} : it->second;
}

double Args::Number(const std::string& flag, double fallback) const {
  const auto text = Get(flag);
  if (!text) return fallback;
  const double value = ParseNumber(*text, flag);
  if (!std::isfinite(value)) throw InputError(flag, "must be finite, got '" + *text + "'");
  return value;
}

int Args::Integer(const std::string& flag, int fallback) const {
  const auto text = Get(flag);
  if (!text) return fallback;
  const double value = ParseNumber(*text, flag);
  if (!std::isfinite(value) || value != std::floor(value) || std::abs(value) > 1e9)
    throw InputError(flag, "expected an integer, got '" + *text + "'");
  return static_cast<int>(value);
}

std::pair<double, double> Args::Range(const std::string& flag, double from, double to) const {
  const auto text = Get(flag);
  if (!text) return {from, to};
  const size_t colon = text->find(':');
  if (colon == std::string::npos) {
    const double v = ParseNumber(*text, flag);
    if (!std::isfinite(v)) throw InputError(flag, "must be finite, got '" + *text + "'");
    return {v, v};
  }
  if (colon == 0 || colon + 1 == text->size())
    throw InputError(flag, "expected FROM:TO or one value, e.g. 5:50 or 8, got '" + *text + "'");
  const double a = ParseNumber(text->substr(0, colon), flag);
  const double b = ParseNumber(text->substr(colon + 1), flag);
  if (!std::isfinite(a) || !std::isfinite(b)) throw InputError(flag, "must be finite, got '" + *text + "'");
  return {a, b};
}

}  // namespace strokelab::cli
