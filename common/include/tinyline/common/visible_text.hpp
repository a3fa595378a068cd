// SPDX-License-Identifier: Apache-2.0
// Text from a file (a bag's topic names, metadata) shown to a person: every
// byte that would not be seen, or would be seen as something else, is
// escaped. Control characters as \n, \t, \r or \xHH, a byte that is no UTF-8
// as \xHH (a terminal shows '?' or nothing), invisible code points (a
// byte-order mark, zero-width and direction marks) and C1 controls as \uXXXX,
// and the backslash itself as \\, so the escaped text reads back unambiguously.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace tinyline::common {

namespace detail {

/// The length of the UTF-8 sequence at s[i] and its code point; 0 when the bytes are no UTF-8.
inline std::size_t utf8_at(std::string_view s, std::size_t i, char32_t& cp) {
  const auto b = [&](std::size_t k) { return static_cast<unsigned char>(s[i + k]); };
  const unsigned char c = b(0);
  std::size_t n = 0;
  if (c < 0x80) return cp = c, 1;
  if (c >= 0xC2 && c <= 0xDF) n = 2, cp = c & 0x1F;
  if (c >= 0xE0 && c <= 0xEF) n = 3, cp = c & 0x0F;
  if (c >= 0xF0 && c <= 0xF4) n = 4, cp = c & 0x07;
  if (n == 0 || i + n > s.size()) return 0;
  for (std::size_t k = 1; k < n; ++k) {
    if ((b(k) & 0xC0) != 0x80) return 0;
    cp = (cp << 6) | (b(k) & 0x3F);
  }
  const bool overlong = (n == 3 && cp < 0x800) || (n == 4 && cp < 0x10000);
  if (overlong || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return 0;
  return n;
}

/// Code points a terminal shows as nothing (or that reorder what follows).
inline bool invisible(char32_t cp) {
  return (cp >= 0x80 && cp <= 0x9F) || cp == 0xAD || cp == 0xFEFF || (cp >= 0x200B && cp <= 0x200F) ||
         (cp >= 0x2028 && cp <= 0x202E) || (cp >= 0x2060 && cp <= 0x2064) || (cp >= 0x2066 && cp <= 0x2069);
}

inline std::string hex(std::uint32_t v, int digits) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out(static_cast<std::size_t>(digits), '0');
  for (int k = digits - 1; k >= 0; --k, v >>= 4) out[static_cast<std::size_t>(k)] = kDigits[v & 15];
  return out;
}

}  // namespace detail

/// `s` with every byte a person would not see escaped (see the file comment).
inline std::string visible(std::string_view s) {
  std::string out;
  out.reserve(s.size());
  for (std::size_t i = 0; i < s.size();) {
    char32_t cp = 0;
    const std::size_t n = detail::utf8_at(s, i, cp);
    if (n == 0) {
      out += "\\x" + detail::hex(static_cast<unsigned char>(s[i]), 2);
      ++i;
      continue;
    }
    if (cp == '\\') {
      out += "\\\\";
    } else if (cp == '\n' || cp == '\t' || cp == '\r') {
      out += cp == '\n' ? "\\n" : cp == '\t' ? "\\t" : "\\r";
    } else if (cp < 0x20 || cp == 0x7F) {
      out += "\\x" + detail::hex(cp, 2);
    } else if (detail::invisible(cp)) {
      out += "\\u" + detail::hex(cp, 4);
    } else {
      out.append(s.substr(i, n));
    }
    i += n;
  }
  return out;
}

}  // namespace tinyline::common
