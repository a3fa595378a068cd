// SPDX-License-Identifier: Apache-2.0
// Test helpers: fill any generated message with pseudo-random values, and
// dump it as JSON (for comparison with an independent decoder).
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <type_traits>
#include <vector>

#include <fmt/format.h>

namespace tinyline::msgtest {

template <class T>
concept Message = requires {
  T::kTypeName;
};

struct Filler {
  std::mt19937_64& rng;
  std::size_t max_seq = 4;

  template <class T>
  void operator()(const char*, T& v) {
    fill(v);
  }

  void fill(bool& b) { b = rng() & 1; }
  template <class T>
  requires std::is_integral_v<T>
  void fill(T& v) { v = static_cast<T>(rng()); }
  template <class T>
  requires std::is_floating_point_v<T>
  void fill(T& v) {
    std::uniform_real_distribution<double> mant(-1.0, 1.0);
    std::uniform_int_distribution<int> ex(-20, 20);
    v = static_cast<T>(std::ldexp(mant(rng), ex(rng)));
  }
  void fill(std::string& s) {
    static const char alphabet[] = "abcXYZ019 _-/:\"\\";
    s.resize(rng() % 9);
    for (char& c : s) c = alphabet[rng() % (sizeof(alphabet) - 1)];
  }
  template <class T>
  void fill(std::vector<T>& v) {
    v.resize(rng() % (max_seq + 1));
    for (std::size_t i = 0; i < v.size(); ++i) {
      if constexpr (std::is_same_v<T, bool>) {
        v[i] = rng() & 1;
      } else {
        fill(v[i]);
      }
    }
  }
  template <class T, std::size_t N>
  void fill(std::array<T, N>& a) {
    for (auto& x : a) fill(x);
  }
  template <Message M>
  void fill(M& m) {
    for_each_field(m, *this);
  }
};

struct JsonDumper {
  std::string out;

  template <class T>
  void operator()(const char* name, const T& v) {
    if (out.back() != '{') out += ", ";
    out += fmt::format("\"{}\": ", name);
    dump(v);
  }

  void dump(bool b) { out += b ? "true" : "false"; }
  template <class T>
  requires std::is_integral_v<T>
  void dump(T v) { out += std::to_string(v); }
  template <class T>
  requires std::is_floating_point_v<T>
  void dump(T v) {
    out += fmt::format("{:.17g}", static_cast<double>(v));  // exact as a double
  }
  void dump(const std::string& s) {
    out += '"';
    for (char c : s) {
      if (c == '"' || c == '\\') out += '\\';
      out += c;
    }
    out += '"';
  }
  template <class C>
  requires requires(const C& c) {
    c.begin();
    c.size();
  } &&(!std::is_same_v<C, std::string>)void dump(const C& c) {
    out += '[';
    bool first = true;
    for (const auto& x : c) {
      if (!first) out += ", ";
      first = false;
      if constexpr (std::is_same_v<std::decay_t<decltype(x)>, bool> || std::is_same_v<C, std::vector<bool>>) {
        dump(static_cast<bool>(x));
      } else {
        dump(x);
      }
    }
    out += ']';
  }
  template <Message M>
  void dump(const M& m) {
    out += '{';
    for_each_field(m, *this);
    out += '}';
  }
};

template <Message M>
std::string to_json(const M& m) {
  JsonDumper d;
  d.out = "";
  d.dump(m);
  return d.out;
}

}  // namespace tinyline::msgtest
