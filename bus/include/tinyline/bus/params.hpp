// SPDX-License-Identifier: Apache-2.0
// Node parameters: declared by the node with a type, a default (taken from
// the core's parameter struct), an optional range or choice list and a
// description; overridden from launch files or the command line. Every
// override is checked when the node is built: an unknown name, a wrong type or
// a value out of range stops start-up with the file, line and reason.
#pragma once

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

namespace tinyline::bus {

using ParamValue = std::variant<bool, std::int64_t, double, std::string, std::vector<bool>, std::vector<std::int64_t>,
                                std::vector<double>, std::vector<std::string>>;

enum class ParamType { Bool, Int, Double, String, BoolArray, IntArray, DoubleArray, StringArray };

std::string_view to_string(ParamType t);
ParamType type_of(const ParamValue& v);
/// YAML-like text of a value: 3, 0.5, true, "text", [1, 2].
std::string format_value(const ParamValue& v);

/// Where a value came from: "file:line:col", or a description such as "command line".
struct SourceLocation {
  std::string file;
  int line = 0;
  int column = 0;
  std::string str() const;
  bool known() const { return !file.empty(); }
};

struct ParamOverride {
  std::string name;
  ParamValue value;
  SourceLocation where;
};

struct ParamConstraints {
  /// A string parameter that names a file. An input must be a regular file
  /// this process can open (within `file_max_bytes`) when the node is built,
  /// so a launch stops at the line that set it before anything starts;
  /// launch checks that no two nodes write one output, and that no node
  /// writes another's input.
  enum class File { None, Input, Output };

  std::optional<double> min;  ///< numbers (and each element of numeric arrays)
  std::optional<double> max;
  std::vector<std::string> choices;  ///< strings: the allowed values (empty = any)
  bool required = false;             ///< must be set from outside (no usable default)
  File file = File::None;
  std::uint64_t file_max_bytes = 0;  ///< Input: the largest file accepted [bytes] (0: any size)
  /// Values that name no file: exact words ("default"), or prefixes ending
  /// in ':' ("public:"). The empty string never names a file.
  std::vector<std::string> not_a_file;
  /// The unit of a number ("m", "px", "s"), shown by `tinyline describe`
  /// and in the docs' tables; not a constraint, it travels with them.
  std::string unit;

  static ParamConstraints range(double lo, double hi) {
    ParamConstraints c;
    c.min = lo;
    c.max = hi;
    return c;
  }
  static ParamConstraints at_least(double lo) {
    ParamConstraints c;
    c.min = lo;
    return c;
  }
  static ParamConstraints one_of(std::vector<std::string> values) {
    ParamConstraints c;
    c.choices = std::move(values);
    return c;
  }
  static ParamConstraints input_file(std::uint64_t max_bytes = 0, std::vector<std::string> not_a_file = {}) {
    ParamConstraints c;
    c.file = File::Input;
    c.file_max_bytes = max_bytes;
    c.not_a_file = std::move(not_a_file);
    return c;
  }
  static ParamConstraints output_file() {
    ParamConstraints c;
    c.file = File::Output;
    return c;
  }
  /// True when `value` is a path under these constraints (see not_a_file).
  bool names_file(const std::string& value) const {
    if (file == File::None || value.empty()) return false;
    for (const auto& w : not_a_file) {
      if (!w.empty() && w.back() == ':' ? value.rfind(w, 0) == 0 : value == w) return false;
    }
    return true;
  }
};

struct ParamDescriptor {
  std::string name;
  ParamType type = ParamType::String;
  ParamValue default_value;
  ParamValue value;
  std::string description;
  ParamConstraints constraints;
  SourceLocation set_from;  ///< where the current value came from (empty: default)
};

class ParamError : public std::runtime_error {
 public:
  ParamError(const SourceLocation& where, const std::string& what)
      : std::runtime_error(where.known() ? where.str() + ": " + what : what), where_(where) {}
  const SourceLocation& where() const { return where_; }

 private:
  SourceLocation where_;
};

/// Parses the text of a command-line value (`name:=value`) with YAML rules:
/// 3 is an int, 3.0 a double, true a bool, [1, 2] an int array, else a string.
ParamValue parse_param_text(std::string_view text);

/// Converts an override to the declared type: ints widen to doubles (and int
/// arrays to double arrays); anything else that differs is an error.
std::optional<ParamValue> coerce(const ParamValue& v, ParamType want);

/// Checks constraints; returns the reason for a violation, or nothing.
std::optional<std::string> violates(const ParamValue& v, const ParamConstraints& c);

// Mapping between C++ parameter types and their stored type.
template <class T>
struct ParamTraits;
template <>
struct ParamTraits<bool> {
  static constexpr ParamType type = ParamType::Bool;
  using Stored = bool;
};
template <>
struct ParamTraits<int> {
  static constexpr ParamType type = ParamType::Int;
  using Stored = std::int64_t;
};
template <>
struct ParamTraits<std::int64_t> {
  static constexpr ParamType type = ParamType::Int;
  using Stored = std::int64_t;
};
template <>
struct ParamTraits<double> {
  static constexpr ParamType type = ParamType::Double;
  using Stored = double;
};
template <>
struct ParamTraits<std::string> {
  static constexpr ParamType type = ParamType::String;
  using Stored = std::string;
};
template <>
struct ParamTraits<std::vector<bool>> {
  static constexpr ParamType type = ParamType::BoolArray;
  using Stored = std::vector<bool>;
};
template <>
struct ParamTraits<std::vector<std::int64_t>> {
  static constexpr ParamType type = ParamType::IntArray;
  using Stored = std::vector<std::int64_t>;
};
template <>
struct ParamTraits<std::vector<double>> {
  static constexpr ParamType type = ParamType::DoubleArray;
  using Stored = std::vector<double>;
};
template <>
struct ParamTraits<std::vector<std::string>> {
  static constexpr ParamType type = ParamType::StringArray;
  using Stored = std::vector<std::string>;
};

}  // namespace tinyline::bus
