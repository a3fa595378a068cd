// SPDX-License-Identifier: Apache-2.0
// Each parameter described once: a settings struct's table names each field
// for the outside world (launch files, `tinyline describe`, the docs) with
// its unit, its range and what it means. The default is the struct's own
// member initialiser; the type is the field's.
//
// A table is a function next to the struct, found by argument-dependent
// lookup, that shows every field to a visitor:
//
//   template <class S, class V> requires common::SettingsOf<S, DbscanParams>
//   void for_each_param(S& p, V&& v) {
//     v(p.eps, {"eps_m", "m", 1e-4, 2.0, "DBSCAN radius"});
//     v(p.min_points, {"min_points", "", 1, 256, "neighbours (self included) of a core point"});
//   }
//
// A struct that holds another shows the inner one's table, its names
// prefixed: `common::nest(p.groups, "groups_", v, "stage 1: ")`. A field whose value is
// one of a few words (an enum) passes the words: `v(p.method, {...}, kMethods)`;
// an optional number is a parameter whose 0 means "none".
// The visitors (the bus's declaration of node parameters, `within_table`
// here) live with whoever needs them; a core needs only this header.
#pragma once

#include <cmath>
#include <concepts>
#include <optional>
#include <charconv>
#include <cstddef>
#include <string>
#include <cstdint>
#include <span>
#include <string_view>
#include <type_traits>
#include <utility>

#include <tinyline/common/status.hpp>

namespace tinyline::common {

/// What a settings field is called outside and what it may hold.
struct Param {
  std::string_view name;         ///< the parameter's name in launch files
  std::string_view unit;         ///< "m", "px", "s", "m/m"; "" for counts, flags and words
  std::optional<double> min{};   ///< numbers: the smallest value accepted
  std::optional<double> max{};   ///< numbers: the largest value accepted
  std::string_view description;  ///< one line, what it means
  /// The field holds the parameter times this: a field in radians set in
  /// degrees has kRadPerDeg, one in bytes set in KiB 1024 (unit, min and max
  /// are the parameter's).
  double scale = 1.0;
};

/// Param::scale of a field in radians whose parameter is in degrees.
inline constexpr double kRadPerDeg = 3.14159265358979323846 / 180.0;

/// One word of a field that takes a few words (an enum).
template <class E>
struct Choice {
  std::string_view word;
  E value;
};

/// A field of a two-valued enum that a launch file sets as a flag:
/// `v(p.correction, {...}, Flag{ArcCorrection::kNone, ArcCorrection::kSecondOrder})`.
template <class E>
struct Flag {
  E off;
  E on;
};
template <class E>
Flag(E, E) -> Flag<E>;  // GCC deduces aggregates by itself; clang before 17 needs the guide

/// A text field that names a file the node reads: `v(p.scene, {...},
/// InputFile{kMaxSceneBytes})`. The node checks it when it is built (a
/// regular file of at most `max_bytes`), so a launch stops at the line that
/// set it; values starting with one of `not_a_file` ("default", "public:")
/// are no file and are left to the node.
struct InputFile {
  std::uint64_t max_bytes = 0;
  std::span<const std::string_view> not_a_file{};
};

/// A text field that names a file the node writes: `v(p.path, {...},
/// OutputFile{})`. A launch checks that no two nodes write one file and that
/// no node writes another's input.
struct OutputFile {};

/// A field the table leaves out on purpose: its value comes from another
/// field (named in `why`), so a parameter for it would be a second way to
/// say one thing. Nothing is declared; the table says so where a reader
/// looks for the field.
template <class T>
constexpr void not_a_parameter(const T& /*field*/, std::string_view /*why*/) {}

/// `S` is `Settings`, const or not (a table serves readers and writers).
template <class S, class Settings>
concept SettingsOf = std::same_as<std::remove_const_t<S>, Settings>;

/// A visitor that prefixes the names (and descriptions) of the fields it passes on.
template <class V>
struct Prefixed {
  V& inner;
  std::string_view prefix;
  std::string_view about;
  template <class T, class... Words>
  void operator()(T& field, Param p, Words&&... words) {
    const std::string name = std::string(prefix) + std::string(p.name);
    const std::string description = std::string(about) + std::string(p.description);
    p.name = name;
    p.description = description;
    inner(field, p, std::forward<Words>(words)...);
  }
};

/// Shows `inner`'s table to `v`, its names prefixed with `prefix` and its
/// descriptions with `about` (what the inner settings are for here).
template <class S, class V>
void nest(S& inner, std::string_view prefix, V& v, std::string_view about = {}) {
  Prefixed<V> pv{v, prefix, about};
  for_each_param(inner, pv);
}

/// The word of `value` in `words` ("" if none).
template <class E, std::size_t N>
std::string_view word_of(E value, const Choice<E> (&words)[N]) {
  for (const auto& c : words)
    if (c.value == value) return c.word;
  return {};
}

namespace detail {
/// The shortest text that reads back as `v`.
inline std::string text(double v) {
  char buf[32];
  return std::string(buf, std::to_chars(buf, buf + sizeof buf, v).ptr);
}
}  // namespace detail

/// Checks every numeric field of `settings` against its table's range (NaN
/// fails): the first field outside it, named as in launch files.
template <class S>
[[nodiscard]] Status within_table(const S& settings) {
  using detail::text;
  Status out;
  auto check = [&out](const auto& field, const Param& p, auto&&...) {
    using T = std::remove_cvref_t<decltype(field)>;
    if constexpr (std::is_arithmetic_v<T> && !std::is_same_v<T, bool>) {
      if (!out.ok()) return;
      const double v = static_cast<double>(field) / p.scale;
      if (std::isnan(v) || (p.min && v < *p.min) || (p.max && v > *p.max)) {
        out = Status::invalid(std::string(p.name) + " must be in [" + (p.min ? text(*p.min) : "-inf") + ", " +
                              (p.max ? text(*p.max) : "inf") + "], got " + text(v));
      }
    }
  };
  for_each_param(settings, check);
  return out;
}

}  // namespace tinyline::common
