// SPDX-License-Identifier: Apache-2.0
#include <tinyline/msg/yaml_writer.hpp>

#include <charconv>
#include <cmath>

namespace tinyline::msg {

void YamlWriter::indent() { out_.append(static_cast<std::size_t>(depth_) * 2, ' '); }

void YamlWriter::key(std::string_view k) {
  if (in_item_) {
    in_item_ = false;
  } else {
    indent();
  }
  out_.append(k);
  out_.push_back(':');
  pending_key_ = true;
}

void YamlWriter::begin_map() {
  if (pending_key_) {
    out_.push_back('\n');
    pending_key_ = false;
    ++depth_;
  } else if (in_item_) {
    ++depth_;  // keys of a map inside a list item: first one follows the dash
  }
}

void YamlWriter::end_map() {
  if (depth_ > 0) --depth_;
  if (in_item_) {  // an item whose map had no keys
    out_.append("{}\n");
    in_item_ = false;
  }
}

void YamlWriter::begin_list(std::size_t n) {
  if (pending_key_) {
    out_.append(n == 0 ? " []\n" : "\n");
    pending_key_ = false;
  }
  ++depth_;
}

void YamlWriter::item() {
  indent();
  out_.append("- ");
  in_item_ = true;
}

void YamlWriter::end_list() {
  if (depth_ > 0) --depth_;
}

void YamlWriter::emit_scalar(const std::string& text) {
  if (pending_key_) {
    out_.push_back(' ');
    pending_key_ = false;
  } else if (in_item_) {
    in_item_ = false;
  } else {
    indent();
  }
  out_.append(text);
  out_.push_back('\n');
}

void YamlWriter::scalar(bool v) { emit_scalar(v ? "true" : "false"); }
void YamlWriter::scalar(const std::string& v) { emit_scalar(quote(v)); }
void YamlWriter::scalar(double v) { emit_scalar(format_double(v)); }

void YamlWriter::begin_inline_list() {
  if (pending_key_) {
    out_.push_back(' ');
    pending_key_ = false;
  } else if (in_item_) {
    in_item_ = false;
  } else {
    indent();
  }
  out_.push_back('[');
  first_inline_ = true;
}

void YamlWriter::inline_item(const std::string& text) {
  if (!first_inline_) out_.append(", ");
  first_inline_ = false;
  out_.append(text);
}

void YamlWriter::end_inline_list(std::size_t elided) {
  out_.push_back(']');
  if (elided != 0) {
    out_.append("  # ");
    out_.append(std::to_string(elided));
    out_.append(" more not shown");
  }
  out_.push_back('\n');
}

std::string YamlWriter::quote(const std::string& s) {
  std::string q = "\"";
  for (unsigned char c : s) {
    switch (c) {
      case '"': q += "\\\""; break;
      case '\\': q += "\\\\"; break;
      case '\n': q += "\\n"; break;
      case '\t': q += "\\t"; break;
      case '\r': q += "\\r"; break;
      default:
        if (c < 0x20) {
          static const char* hex = "0123456789abcdef";
          q += "\\x";
          q += hex[c >> 4];
          q += hex[c & 15];
        } else {
          q += static_cast<char>(c);
        }
    }
  }
  q += '"';
  return q;
}

std::string YamlWriter::format_double(double v) {
  if (std::isnan(v)) return ".nan";
  if (std::isinf(v)) return v > 0 ? ".inf" : "-.inf";
  char buf[64];
  auto res = std::to_chars(buf, buf + sizeof(buf), v);  // shortest round-trip form
  std::string s(buf, res.ptr);
  if (s.find_first_of(".e") == std::string::npos) s += ".0";
  return s;
}

}  // namespace tinyline::msg
