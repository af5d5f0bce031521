// Parsing numbers from user text with errors that name the field.
#pragma once

#include <string>
#include <string_view>

namespace strokelab {

// Parses a decimal number ("inf" and "-inf" allowed, NaN refused); throws InputError(field, ...).
double ParseNumber(std::string_view text, const std::string& field);

}  // namespace strokelab
