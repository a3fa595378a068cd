// SPDX-License-Identifier: Apache-2.0
// Reading the fields of a hand-written YAML file (a calibration, the
// measured figures): every error names the file, the line and the field,
// "calib.yaml:12: field 'ratio.range': expected a number", and is thrown as
// the reader's own error type. For targets that link yaml-cpp (common itself
// does not).
#pragma once

#include <cmath>
#include <cstddef>
#include <initializer_list>
#include <limits>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <yaml-cpp/yaml.h>

namespace tinyline::common {

template <class Error>
class YamlFields {
 public:
  /// `source` names the file in errors; a list longer than
  /// `max_list_length` is refused (a broken or hostile file).
  explicit YamlFields(std::string source, std::size_t max_list_length = std::numeric_limits<std::size_t>::max())
      : source_(std::move(source)), max_list_length_(max_list_length) {}

  [[noreturn]] void fail(const YAML::Node& at, const std::string& field, const std::string& what) const {
    const auto mark = at.Mark();
    const std::string where = mark.line >= 0 ? source_ + ":" + std::to_string(mark.line + 1) : source_;
    throw Error(where + ": field '" + field + "': " + what);
  }

  /// "parent.key", or "key" at the top.
  static std::string join(const std::string& parent, std::string_view key) {
    return parent.empty() ? std::string(key) : parent + "." + std::string(key);
  }

  /// A mapping of known keys, each at most once (yaml-cpp keeps a repeated
  /// key and lookups see the first: the second would be ignored silently).
  void only_keys(const YAML::Node& map, const std::string& field, std::initializer_list<std::string_view> known) const {
    if (!map.IsMap()) fail(map, field, "expected a mapping");
    std::set<std::string> seen;
    for (const auto& kv : map) {
      if (!kv.first.IsScalar()) fail(kv.first, field, "expected a key, not a list or mapping");
      const std::string key = kv.first.Scalar();
      bool ok = false;
      for (auto k : known) ok = ok || k == key;
      if (!ok) {
        std::string list;
        for (auto k : known) list += (list.empty() ? "" : ", ") + std::string(k);
        fail(kv.first, join(field, key), "unknown key (known here: " + list + ")");
      }
      if (!seen.insert(key).second) fail(kv.first, join(field, key), "given twice");
    }
  }

  /// map[key] of the mapping `parent`; fails when it is missing.
  YAML::Node required(const YAML::Node& map, const std::string& parent, std::string_view key) const {
    if (!map.IsMap()) fail(map, parent, "expected a mapping");
    const YAML::Node n = map[std::string(key)];
    if (!n) fail(map, join(parent, key), "missing");
    return n;
  }

  /// A finite number.
  double number(const YAML::Node& n, const std::string& field) const {
    if (!n.IsScalar()) fail(n, field, "expected a number");
    double v = 0.0;
    try {
      v = n.as<double>();
    } catch (const YAML::Exception&) {
      fail(n, field, "'" + n.Scalar() + "' is not a number");
    }
    if (!std::isfinite(v)) fail(n, field, "must be finite");
    return v;
  }
  double number(const YAML::Node& map, const std::string& parent, std::string_view key) const {
    return number(required(map, parent, key), join(parent, key));
  }
  /// The number at map[key], or `fallback` when there is none.
  double number_or(const YAML::Node& map, const std::string& parent, std::string_view key, double fallback) const {
    const YAML::Node n = map[std::string(key)];
    return n ? number(n, join(parent, key)) : fallback;
  }

  /// A list of finite numbers.
  std::vector<double> numbers(const YAML::Node& n, const std::string& field) const {
    bounded_list(n, field, "numbers");
    std::vector<double> v;
    v.reserve(n.size());
    for (std::size_t i = 0; i < n.size(); ++i) v.push_back(number(n[i], field + "[" + std::to_string(i) + "]"));
    return v;
  }
  std::vector<double> numbers(const YAML::Node& map, const std::string& parent, std::string_view key) const {
    return numbers(required(map, parent, key), join(parent, key));
  }

  std::vector<long> integers(const YAML::Node& n, const std::string& field) const {
    bounded_list(n, field, "integers");
    std::vector<long> v;
    for (std::size_t i = 0; i < n.size(); ++i) {
      long x = 0;
      try {
        x = n[i].as<long>();
      } catch (const YAML::Exception&) {
        fail(n[i], field + "[" + std::to_string(i) + "]", "'" + n[i].Scalar() + "' is not an integer");
      }
      v.push_back(x);
    }
    return v;
  }

  std::string text(const YAML::Node& n, const std::string& field) const {
    if (!n.IsScalar()) fail(n, field, "expected text");
    return n.Scalar();
  }
  std::string text(const YAML::Node& map, const std::string& parent, std::string_view key) const {
    return text(required(map, parent, key), join(parent, key));
  }

 private:
  void bounded_list(const YAML::Node& n, const std::string& field, const char* of) const {
    if (!n.IsSequence()) fail(n, field, std::string("expected a list of ") + of);
    if (n.size() > max_list_length_) {
      fail(n, field, "has " + std::to_string(n.size()) + " values, more than " + std::to_string(max_list_length_));
    }
  }

  std::string source_;
  std::size_t max_list_length_;
};

}  // namespace tinyline::common
