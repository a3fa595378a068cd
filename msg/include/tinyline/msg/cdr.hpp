// SPDX-License-Identifier: Apache-2.0
// CDR (XCDR1, the encoding ROS 2 uses on the wire and in bags).
//
// A serialized message is a 4-byte encapsulation header (0x00 0x01 0x00 0x00
// for little-endian CDR) followed by the payload. Primitives are aligned to
// their own size (8 for 64-bit types) relative to the start of the payload;
// strings are a uint32 length that counts the terminating NUL, the bytes and
// the NUL; sequences are a uint32 count and their elements; fixed arrays are
// their elements only.
//
// The reader never reads past the end of its buffer and never allocates more
// than the remaining bytes could describe: every failure is a cdr::Error that
// names the field and the byte offset.
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace tinyline::cdr {

static_assert(std::endian::native == std::endian::little, "tinyline's CDR writer assumes a little-endian host");

inline constexpr std::uint8_t kEncapsulationLE[4] = {0x00, 0x01, 0x00, 0x00};
inline constexpr std::uint8_t kEncapsulationBE[4] = {0x00, 0x00, 0x00, 0x00};

class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Appends one encapsulated CDR message to a byte vector.
class Writer {
 public:
  /// Writes the little-endian encapsulation header at the end of `out`.
  explicit Writer(std::vector<std::uint8_t>& out) : out_(out) {
    out_.insert(out_.end(), std::begin(kEncapsulationLE), std::end(kEncapsulationLE));
    origin_ = out_.size();
  }

  template <class T>
  void put(T v) {
    static_assert(std::is_arithmetic_v<T>);
    align(sizeof(T));
    const auto pos = out_.size();
    out_.resize(pos + sizeof(T));
    std::memcpy(out_.data() + pos, &v, sizeof(T));
  }

  void put(bool v) { out_.push_back(v ? 1 : 0); }

  template <class T>
  void put_array(const T* data, std::size_t n) {
    static_assert(std::is_arithmetic_v<T> && !std::is_same_v<T, bool>);
    if (n == 0) return;
    align(sizeof(T));
    const auto pos = out_.size();
    out_.resize(pos + n * sizeof(T));
    std::memcpy(out_.data() + pos, data, n * sizeof(T));
  }

  /// Sequence length prefix; `bound` > 0 is the declared upper bound.
  void put_count(std::size_t n, std::size_t bound, const char* field) {
    if (bound != 0 && n > bound) {
      throw Error("field '" + std::string(field) + "' has " + std::to_string(n) + " elements, more than its bound " +
                  std::to_string(bound));
    }
    if (n > UINT32_MAX) throw Error("field '" + std::string(field) + "' is too long for CDR");
    put(static_cast<std::uint32_t>(n));
  }

  void put_string(std::string_view s, std::size_t bound, const char* field) {
    if (bound != 0 && s.size() > bound) {
      throw Error("string field '" + std::string(field) + "' has " + std::to_string(s.size()) +
                  " characters, more than its bound " + std::to_string(bound));
    }
    put(static_cast<std::uint32_t>(s.size() + 1));
    out_.insert(out_.end(), s.begin(), s.end());
    out_.push_back(0);
  }

  std::size_t payload_size() const { return out_.size() - origin_; }

 private:
  void align(std::size_t a) {
    const std::size_t pos = out_.size() - origin_;
    const std::size_t pad = (a - pos % a) % a;
    out_.insert(out_.end(), pad, 0);
  }

  std::vector<std::uint8_t>& out_;
  std::size_t origin_ = 0;
};

/// Reads one CDR payload (the bytes after the encapsulation header).
class Reader {
 public:
  Reader(std::span<const std::uint8_t> payload, bool little_endian) : data_(payload), swap_(!little_endian) {}

  /// Names the field being read, for error messages (a pointer store, no cost).
  void at(const char* field) { field_ = field; }

  template <class T>
  T get() {
    static_assert(std::is_arithmetic_v<T>);
    align(sizeof(T));
    need(sizeof(T));
    T v;
    std::memcpy(&v, data_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    if constexpr (sizeof(T) > 1) {
      if (swap_) v = byteswap(v);
    }
    return v;
  }

  template <class T>
  void get_array(T* out, std::size_t n) {
    static_assert(std::is_arithmetic_v<T> && !std::is_same_v<T, bool>);
    if (n == 0) return;
    align(sizeof(T));
    need(n * sizeof(T));
    std::memcpy(out, data_.data() + pos_, n * sizeof(T));
    pos_ += n * sizeof(T);
    if constexpr (sizeof(T) > 1) {
      if (swap_) {
        for (std::size_t i = 0; i < n; ++i) out[i] = byteswap(out[i]);
      }
    }
  }

  /// A sequence count, checked against the bytes left (each element needs at
  /// least `min_elem_bytes`) so a corrupt count cannot trigger a huge allocation.
  std::size_t get_count(std::size_t min_elem_bytes, std::size_t bound) {
    const std::size_t start = pos_;
    const auto n = static_cast<std::size_t>(get<std::uint32_t>());
    if (bound != 0 && n > bound) {
      fail("sequence of " + std::to_string(n) + " elements exceeds its bound " + std::to_string(bound), start);
    }
    if (n > remaining() / min_elem_bytes) {
      fail("sequence claims " + std::to_string(n) + " elements but only " + std::to_string(remaining()) +
               " bytes remain",
           start);
    }
    return n;
  }

  void get_string(std::string& out, std::size_t bound) {
    const std::size_t start = pos_;
    const auto len = static_cast<std::size_t>(get<std::uint32_t>());
    if (len == 0) {  // tolerated: some writers encode "" without the NUL
      out.clear();
      return;
    }
    need(len);
    const char* p = reinterpret_cast<const char*>(data_.data() + pos_);
    if (p[len - 1] != '\0') fail("string is not NUL-terminated", start);
    if (bound != 0 && len - 1 > bound) {
      fail("string of " + std::to_string(len - 1) + " characters exceeds its bound " + std::to_string(bound), start);
    }
    out.assign(p, len - 1);
    pos_ += len;
  }

  /// The next `n` bytes where they lie (a byte sequence's elements read in
  /// place, no copy): valid while the payload is.
  std::span<const std::uint8_t> get_bytes(std::size_t n) {
    need(n);
    const auto s = data_.subspan(pos_, n);
    pos_ += n;
    return s;
  }

  std::size_t position() const { return pos_; }
  std::size_t remaining() const { return pos_ >= data_.size() ? 0 : data_.size() - pos_; }

 private:
  template <class T>
  static T byteswap(T v) {
    std::uint8_t b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
    std::memcpy(&v, b, sizeof(T));
    return v;
  }

  void align(std::size_t a) {
    const std::size_t pad = (a - pos_ % a) % a;
    // Trailing padding may be absent at the very end; only fail when a value follows.
    pos_ = pos_ + pad <= data_.size() ? pos_ + pad : data_.size() + 1;
  }

  void need(std::size_t n) {
    if (pos_ > data_.size() || n > data_.size() - pos_) {
      const std::size_t have = pos_ > data_.size() ? 0 : data_.size() - pos_;
      fail("truncated: need " + std::to_string(n) + " bytes, " + std::to_string(have) + " left", pos_);
    }
  }

  [[noreturn]] void fail(const std::string& what, std::size_t offset) const {
    throw Error("CDR field '" + std::string(field_) + "' at payload offset " + std::to_string(offset) + ": " + what);
  }

  std::span<const std::uint8_t> data_;
  std::size_t pos_ = 0;
  bool swap_ = false;
  const char* field_ = "<start>";
};

}  // namespace tinyline::cdr
