// SPDX-License-Identifier: Apache-2.0
// A node declares a core's settings from the settings' table
// (<tinyline/common/param_table.hpp>): every field becomes a parameter with
// the table's name, unit, range and description, its default read from the
// struct, its value written back into it. One call per settings struct:
//
//   clusterer_(bus::declared_settings<TwoStageParams>(*this))
#pragma once

#include <cstdint>
#include <cstddef>
#include <iterator>
#include <optional>
#include <string_view>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include <tinyline/bus/node.hpp>
#include <tinyline/common/param_table.hpp>

namespace tinyline::bus {

/// The bus's constraints for a table entry: its range and unit.
inline ParamConstraints constraints_of(const common::Param& p) {
  ParamConstraints c;
  c.min = p.min;
  c.max = p.max;
  c.unit = std::string(p.unit);
  return c;
}

/// Declares one field as a parameter and stores the value given.
template <class T>
void declare_field(Node& node, T& field, const common::Param& p) {
  const std::string name(p.name);
  const std::string what(p.description);
  if constexpr (std::is_floating_point_v<T>) {
    // Declared in the parameter's unit: the field is the parameter times p.scale.
    field = static_cast<T>(p.scale * node.declare_parameter<double>(name, field / p.scale, what, constraints_of(p)));
  } else if constexpr (std::is_same_v<T, bool> || std::is_same_v<T, double> || std::is_same_v<T, float> ||
                       std::is_same_v<T, std::string> || std::is_same_v<T, std::vector<double>> ||
                       std::is_same_v<T, std::vector<std::string>>) {
    field = node.declare_parameter(name, field, what, constraints_of(p));
  } else if constexpr (requires {
                         T::RowsAtCompileTime;
                         T::SizeAtCompileTime;
                       }) {
    // A fixed-size Eigen vector: an array of exactly that many numbers.
    constexpr auto n = static_cast<std::size_t>(T::SizeAtCompileTime);
    const std::vector<double> d(field.data(), field.data() + n);
    const auto given = node.declare_parameter(name, d, what, constraints_of(p));
    if (given.size() != n) {
      throw ParamError({}, "node '" + node.full_name() + "': " + name + " needs " + std::to_string(n) +
                               " numbers, got " + std::to_string(given.size()));
    }
    for (std::size_t i = 0; i < n; ++i) field[static_cast<Eigen::Index>(i)] = given[i];
  } else if constexpr (std::is_integral_v<T>) {
    // Declared in the parameter's unit: the field is the parameter times p.scale (bytes set in KiB).
    const auto scale = static_cast<std::int64_t>(p.scale);
    field = static_cast<T>(scale * node.declare_parameter<std::int64_t>(name, static_cast<std::int64_t>(field) / scale,
                                                                        what, constraints_of(p)));
  } else {
    static_assert(std::is_same_v<T, void>, "a parameter table field of a type the bus cannot declare");
  }
}

/// Declares an optional number: 0 (the default when unset) means none.
inline void declare_field(Node& node, std::optional<double>& field, const common::Param& p) {
  const double v =
      node.declare_parameter(std::string(p.name), field.value_or(0.0), std::string(p.description), constraints_of(p));
  field = v == 0.0 ? std::nullopt : std::optional<double>(v);
}

/// Declares a table of (x, y) pairs as one array, x0, y0, x1, y1, ...
inline void declare_field(Node& node, std::vector<std::pair<double, double>>& field, const common::Param& p) {
  std::vector<double> flat;
  for (const auto& [x, y] : field) flat.insert(flat.end(), {x, y});
  flat = node.declare_parameter(std::string(p.name), flat, std::string(p.description), constraints_of(p));
  if (flat.empty() || flat.size() % 2 != 0) {
    throw ParamError({}, "node '" + node.full_name() + "': " + std::string(p.name) +
                             " needs pairs of numbers (x0, y0, x1, y1, ...), got " + std::to_string(flat.size()));
  }
  field.clear();
  for (std::size_t i = 0; i < flat.size(); i += 2) field.emplace_back(flat[i], flat[i + 1]);
}

/// Declares a two-valued enum as a flag.
template <class E>
void declare_field(Node& node, E& field, const common::Param& p, const common::Flag<E>& flag) {
  const bool on =
      node.declare_parameter(std::string(p.name), field == flag.on, std::string(p.description), constraints_of(p));
  field = on ? flag.on : flag.off;
}

/// Declares a field that holds one of a few words (an enum).
template <class E, std::size_t N>
void declare_field(Node& node, E& field, const common::Param& p, const common::Choice<E> (&words)[N]) {
  std::vector<std::string> allowed;
  for (const auto& w : words) allowed.emplace_back(w.word);
  ParamConstraints c = ParamConstraints::one_of(allowed);
  c.unit = std::string(p.unit);
  const std::string chosen = node.declare_parameter(std::string(p.name), std::string(common::word_of(field, words)),
                                                    std::string(p.description), std::move(c));
  for (const auto& w : words)
    if (w.word == chosen) field = w.value;
}

/// Declares a text field that holds one of a few words.
template <std::size_t N>
void declare_field(Node& node, std::string& field, const common::Param& p, const std::string_view (&words)[N]) {
  ParamConstraints c = ParamConstraints::one_of(std::vector<std::string>(std::begin(words), std::end(words)));
  c.unit = std::string(p.unit);
  field = node.declare_parameter(std::string(p.name), field, std::string(p.description), std::move(c));
}

/// Declares a text field that names an input file (checked when declared).
inline void declare_field(Node& node, std::string& field, const common::Param& p, const common::InputFile& file) {
  ParamConstraints c = ParamConstraints::input_file(
      file.max_bytes, std::vector<std::string>(file.not_a_file.begin(), file.not_a_file.end()));
  c.unit = std::string(p.unit);
  field = node.declare_parameter(std::string(p.name), field, std::string(p.description), std::move(c));
}

/// Declares a text field that names a file the node writes.
inline void declare_field(Node& node, std::string& field, const common::Param& p, const common::OutputFile&) {
  ParamConstraints c = ParamConstraints::output_file();
  c.unit = std::string(p.unit);
  field = node.declare_parameter(std::string(p.name), field, std::string(p.description), std::move(c));
}

/// Declares every field of `settings`' table on `node` (see above), the
/// names prefixed with `prefix` when one node holds two of a kind.
template <class S>
void declare_params(Node& node, S& settings, std::string_view prefix = {}) {
  auto declare = [&node](auto& field, const common::Param& p, auto&&... words) {
    declare_field(node, field, p, words...);
  };
  common::nest(settings, prefix, declare);
}

/// The settings of a core as this node's parameters give them: the struct's
/// defaults, overridden from the launch file, each checked against its
/// table's range, and all of them against the core's rules (`validate(s)`,
/// found next to the struct); throws ParamError naming what is wrong.
template <class S>
[[nodiscard]] S declared_settings(Node& node) {
  S settings;
  declare_params(node, settings);
  node.require_valid(validate(settings));
  return settings;
}

}  // namespace tinyline::bus
