// SPDX-License-Identifier: Apache-2.0
// A small block-style YAML emitter for decoded messages (`bag echo`,
// `topic echo`). Long numeric arrays can be elided past a limit.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace tinyline::msg {

class YamlWriter {
 public:
  /// max_array: print at most this many elements of a numeric array (0 = all).
  explicit YamlWriter(std::size_t max_array = 0) : max_array_(max_array) {}

  void key(std::string_view k);
  void begin_map();
  void end_map();
  void begin_list(std::size_t n);
  void item();
  void end_list();

  void scalar(bool v);
  void scalar(const std::string& v);
  void scalar(double v);
  void scalar(float v) { scalar(static_cast<double>(v)); }
  template <class T>
  requires std::is_integral_v<T>
  void scalar(T v) {
    if constexpr (std::is_signed_v<T>) {
      emit_scalar(std::to_string(static_cast<long long>(v)));
    } else {
      emit_scalar(std::to_string(static_cast<unsigned long long>(v)));
    }
  }

  template <class T>
  void scalar_list(const T* data, std::size_t n) {
    begin_inline_list();
    const std::size_t shown = max_array_ != 0 && n > max_array_ ? max_array_ : n;
    for (std::size_t i = 0; i < shown; ++i) {
      if constexpr (std::is_same_v<T, std::string>) {
        inline_item(quote(data[i]));
      } else if constexpr (std::is_floating_point_v<T>) {
        inline_item(format_double(static_cast<double>(data[i])));
      } else if constexpr (std::is_signed_v<T>) {
        inline_item(std::to_string(static_cast<long long>(data[i])));
      } else {
        inline_item(std::to_string(static_cast<unsigned long long>(data[i])));
      }
    }
    end_inline_list(n - shown);
  }

  const std::string& str() const { return out_; }

  static std::string quote(const std::string& s);
  static std::string format_double(double v);

 private:
  void emit_scalar(const std::string& text);
  void begin_inline_list();
  void inline_item(const std::string& text);
  void end_inline_list(std::size_t elided);
  void indent();

  std::string out_;
  int depth_ = 0;
  bool pending_key_ = false;
  bool in_item_ = false;
  bool first_inline_ = true;
  std::size_t max_array_ = 0;
};

}  // namespace tinyline::msg
