#pragma once
/// \file
/// Whole-field number parsing for text contracts (CSV indexes, YAML scalars): "100.802xyz",
/// "0x64", "", "nan" and "inf" are errors, not numbers. Leading and trailing blanks are
/// allowed.
#include <optional>
#include <string_view>

namespace rgbdt::core {

/// A finite decimal number written in full (optionally with an exponent), or nullopt.
std::optional<double> parse_finite_double(std::string_view text);

/// A decimal integer written in full, within [lo, hi], or nullopt.
std::optional<long long> parse_integer(std::string_view text, long long lo, long long hi);

}  // namespace rgbdt::core
