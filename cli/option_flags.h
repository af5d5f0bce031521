// The fit's and the diagnosis's options as flags, from their tables (FitOptionFields,
// DiagnoseOptionFields in core): which flags take a value and which are switches, reading them, and
// the flag that set a field IsValid names.
#pragma once

#include <string>
#include <variant>
#include <vector>

#include "args.h"
#include "strokelab/identify/fit.h"

namespace strokelab::cli {

// Appends the table's flags to the valued flags and the switches of an Args.
template <class Options>
void AddOptionFlags(const std::vector<OptionInfo<Options>>& table, std::vector<std::string>* valued,
                    std::vector<std::string>* switches) {
  for (const OptionInfo<Options>& info : table) {
    if (info.flag == nullptr) continue;
    (std::holds_alternative<bool Options::*>(info.member) ? switches : valued)->push_back(info.flag);
  }
}

// Sets the options whose flags were given, in table order; a switch sets its bool (or clears it,
// flag_clears) whether given or not. Throws InputError naming the flag of a malformed number.
template <class Options>
void ReadOptionFlags(const Args& args, const std::vector<OptionInfo<Options>>& table, Options* options) {
  for (const OptionInfo<Options>& info : table) {
    if (info.flag == nullptr) continue;
    if (const auto* member = std::get_if<int Options::*>(&info.member))
      options->**member = args.Integer(info.flag, options->**member);
    else if (const auto* member = std::get_if<double Options::*>(&info.member))
      options->**member = args.Number(info.flag, options->**member);
    else
      options->*std::get<bool Options::*>(info.member) = args.Has(info.flag) != info.flag_clears;
  }
}

// The flag that sets an IsValid field, else the field itself.
template <class Options>
std::string FlagOf(const std::vector<OptionInfo<Options>>& table, const std::string& field) {
  const OptionInfo<Options>* info = FindOption(table, field);
  return info != nullptr && info->flag != nullptr ? info->flag : field;
}

}  // namespace strokelab::cli
