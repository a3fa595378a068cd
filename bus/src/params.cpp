// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bus/params.hpp>

#include <yaml-cpp/yaml.h>

#include <cmath>

#include <fmt/format.h>

#include <tinyline/bus/detail/yaml_params.hpp>

namespace tinyline::bus {

std::string_view to_string(ParamType t) {
  switch (t) {
    case ParamType::Bool: return "bool";
    case ParamType::Int: return "integer";
    case ParamType::Double: return "double";
    case ParamType::String: return "string";
    case ParamType::BoolArray: return "bool array";
    case ParamType::IntArray: return "integer array";
    case ParamType::DoubleArray: return "double array";
    case ParamType::StringArray: return "string array";
  }
  return "?";
}

ParamType type_of(const ParamValue& v) { return static_cast<ParamType>(v.index()); }

namespace {
std::string fmt_double(double d) {
  std::string s = fmt::format("{}", d);
  if (s.find_first_of(".eni") == std::string::npos) s += ".0";
  return s;
}
std::string quote(const std::string& s) { return "\"" + s + "\""; }
}  // namespace

std::string format_value(const ParamValue& v) {
  return std::visit(
      [](const auto& x) -> std::string {
        using T = std::decay_t<decltype(x)>;
        if constexpr (std::is_same_v<T, bool>) {
          return x ? "true" : "false";
        } else if constexpr (std::is_same_v<T, std::int64_t>) {
          return std::to_string(x);
        } else if constexpr (std::is_same_v<T, double>) {
          return fmt_double(x);
        } else if constexpr (std::is_same_v<T, std::string>) {
          return quote(x);
        } else {
          std::string s = "[";
          for (std::size_t i = 0; i < x.size(); ++i) {
            if (i) s += ", ";
            using E = typename T::value_type;
            if constexpr (std::is_same_v<E, bool>) {
              s += x[i] ? "true" : "false";
            } else if constexpr (std::is_same_v<E, std::int64_t>) {
              s += std::to_string(x[i]);
            } else if constexpr (std::is_same_v<E, double>) {
              s += fmt_double(x[i]);
            } else {
              s += quote(x[i]);
            }
          }
          return s + "]";
        }
      },
      v);
}

std::string SourceLocation::str() const {
  if (line <= 0) return file;
  if (column <= 0) return fmt::format("{}:{}", file, line);
  return fmt::format("{}:{}:{}", file, line, column);
}

namespace {

enum class ScalarKind { Bool, Int, Double, String };

ScalarKind classify(const YAML::Node& n, bool& b, std::int64_t& i, double& d) {
  const std::string& s = n.Scalar();
  if (n.Tag() == "!") return ScalarKind::String;  // quoted: always a string
  if (s == "true" || s == "True" || s == "TRUE") {
    b = true;
    return ScalarKind::Bool;
  }
  if (s == "false" || s == "False" || s == "FALSE") {
    b = false;
    return ScalarKind::Bool;
  }
  try {
    std::size_t pos = 0;
    const long long v = std::stoll(s, &pos, 0);
    if (pos == s.size()) {
      i = v;
      return ScalarKind::Int;
    }
  } catch (...) {}
  try {
    std::size_t pos = 0;
    const double v = std::stod(s, &pos);
    if (pos == s.size()) {
      d = v;
      return ScalarKind::Double;
    }
  } catch (...) {}
  if (s == ".nan" || s == ".NaN") {
    d = std::nan("");
    return ScalarKind::Double;
  }
  if (s == ".inf" || s == "+.inf") {
    d = INFINITY;
    return ScalarKind::Double;
  }
  if (s == "-.inf") {
    d = -INFINITY;
    return ScalarKind::Double;
  }
  return ScalarKind::String;
}

}  // namespace

std::optional<ParamValue> param_from_yaml(const YAML::Node& n, std::string* why) {
  bool b = false;
  std::int64_t i = 0;
  double d = 0;
  if (n.IsScalar()) {
    switch (classify(n, b, i, d)) {
      case ScalarKind::Bool: return ParamValue(b);
      case ScalarKind::Int: return ParamValue(i);
      case ScalarKind::Double: return ParamValue(d);
      case ScalarKind::String: return ParamValue(n.Scalar());
    }
  }
  if (n.IsNull()) {
    if (why) *why = "no value given";
    return std::nullopt;
  }
  if (n.IsSequence()) {
    std::vector<bool> bs;
    std::vector<std::int64_t> is;
    std::vector<double> ds;
    std::vector<std::string> ss;
    bool any_bool = false, any_int = false, any_double = false, any_string = false;
    for (const auto& e : n) {
      if (!e.IsScalar()) {
        if (why) *why = "arrays may only hold scalars";
        return std::nullopt;
      }
      switch (classify(e, b, i, d)) {
        case ScalarKind::Bool:
          any_bool = true;
          bs.push_back(b);
          break;
        case ScalarKind::Int:
          any_int = true;
          is.push_back(i);
          ds.push_back(static_cast<double>(i));
          break;
        case ScalarKind::Double:
          any_double = true;
          ds.push_back(d);
          break;
        case ScalarKind::String: any_string = true; break;
      }
      ss.push_back(e.Scalar());
    }
    const int kinds = int(any_bool) + int(any_int || any_double) + int(any_string);
    if (kinds > 1) {
      if (why) *why = "array mixes element types";
      return std::nullopt;
    }
    if (any_bool) return ParamValue(bs);
    if (any_double) return ParamValue(ds);
    if (any_int) return ParamValue(is);
    return ParamValue(ss);  // strings, or an empty list
  }
  if (why) *why = "a parameter value must be a scalar or a list";
  return std::nullopt;
}

ParamValue parse_param_text(std::string_view text) {
  YAML::Node n;
  try {
    n = YAML::Load(std::string(text));
  } catch (const YAML::Exception&) {
    return ParamValue(std::string(text));
  }
  std::string why;
  if (auto v = param_from_yaml(n, &why)) return *v;
  return ParamValue(std::string(text));
}

std::optional<ParamValue> coerce(const ParamValue& v, ParamType want) {
  const ParamType have = type_of(v);
  if (have == want) return v;
  if (have == ParamType::Int && want == ParamType::Double) {
    return ParamValue(static_cast<double>(std::get<std::int64_t>(v)));
  }
  if (have == ParamType::IntArray && want == ParamType::DoubleArray) {
    const auto& a = std::get<std::vector<std::int64_t>>(v);
    return ParamValue(std::vector<double>(a.begin(), a.end()));
  }
  // An empty list parses as a string array; it fits any array type.
  if (have == ParamType::StringArray && std::get<std::vector<std::string>>(v).empty()) {
    switch (want) {
      case ParamType::BoolArray: return ParamValue(std::vector<bool>{});
      case ParamType::IntArray: return ParamValue(std::vector<std::int64_t>{});
      case ParamType::DoubleArray: return ParamValue(std::vector<double>{});
      default: break;
    }
  }
  return std::nullopt;
}

std::optional<std::string> violates(const ParamValue& v, const ParamConstraints& c) {
  auto check_num = [&](double x) -> std::optional<std::string> {
    if (std::isnan(x) && (c.min || c.max)) return std::string("is NaN");
    if (c.min && x < *c.min) return fmt::format("{} is below the minimum {}", fmt_double(x), fmt_double(*c.min));
    if (c.max && x > *c.max) return fmt::format("{} is above the maximum {}", fmt_double(x), fmt_double(*c.max));
    return std::nullopt;
  };
  if (auto* i = std::get_if<std::int64_t>(&v)) return check_num(static_cast<double>(*i));
  if (auto* d = std::get_if<double>(&v)) return check_num(*d);
  if (auto* s = std::get_if<std::string>(&v)) {
    if (!c.choices.empty()) {
      for (const auto& ch : c.choices)
        if (ch == *s) return std::nullopt;
      std::string list;
      for (const auto& ch : c.choices) list += (list.empty() ? "" : ", ") + quote(ch);
      return fmt::format("\"{}\" is not one of {}", *s, list);
    }
  }
  if (auto* a = std::get_if<std::vector<double>>(&v)) {
    for (double x : *a)
      if (auto r = check_num(x)) return "element " + *r;
  }
  if (auto* a = std::get_if<std::vector<std::int64_t>>(&v)) {
    for (auto x : *a)
      if (auto r = check_num(static_cast<double>(x))) return "element " + *r;
  }
  return std::nullopt;
}

}  // namespace tinyline::bus
