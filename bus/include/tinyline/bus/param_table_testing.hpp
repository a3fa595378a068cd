// SPDX-License-Identifier: Apache-2.0
// Test helpers for parameter tables (<tinyline/bus/param_table.hpp>): what a
// table says the defaults are, and what a node declared, by name.
#pragma once

#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <string_view>
#include <type_traits>
#include <variant>

#include <tinyline/bus/node.hpp>
#include <tinyline/common/param_table.hpp>

namespace tinyline::bus::testing {

/// name -> default of every number or flag in `S`'s table, the names
/// prefixed with `prefix` as a node holding it nested declares them.
template <class S>
std::map<std::string, double> table_defaults(std::string_view prefix = {}) {
  std::map<std::string, double> out;
  S s;
  auto collect = [&out](auto& field, const common::Param& p, auto&&...) {
    using T = std::remove_cvref_t<decltype(field)>;
    if constexpr (std::is_arithmetic_v<T>) out[std::string(p.name)] = static_cast<double>(field);
  };
  common::nest(s, prefix, collect);
  return out;
}

/// A number or flag parameter's value as a double; NaN (equal to nothing)
/// for any other kind.
inline double param_number(const ParamValue& v) {
  if (const auto* d = std::get_if<double>(&v)) return *d;
  if (const auto* i = std::get_if<std::int64_t>(&v)) return static_cast<double>(*i);
  if (const auto* b = std::get_if<bool>(&v)) return *b ? 1.0 : 0.0;
  return std::numeric_limits<double>::quiet_NaN();
}

/// The parameters `n` declared, by name.
inline std::map<std::string, const ParamDescriptor*> params_by_name(const Node& n) {
  std::map<std::string, const ParamDescriptor*> out;
  for (const auto& d : n.parameters()) out[d.name] = &d;
  return out;
}

}  // namespace tinyline::bus::testing
