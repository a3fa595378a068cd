// SPDX-License-Identifier: Apache-2.0
// Little-endian field encoding of MCAP records (internal).
#pragma once

#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <fmt/format.h>

#include <tinyline/bag/records.hpp>
#include <tinyline/bag/status.hpp>

namespace tinyline::bag::wire {

template <class T>
inline void put(std::vector<std::uint8_t>& out, T v) {
  static_assert(std::is_integral_v<T>);
  const auto pos = out.size();
  out.resize(pos + sizeof(T));
  std::memcpy(out.data() + pos, &v, sizeof(T));  // little-endian host (checked in cdr.hpp)
}

inline void put_bytes(std::vector<std::uint8_t>& out, std::span<const std::uint8_t> b) {
  out.insert(out.end(), b.begin(), b.end());
}

inline void put_string(std::vector<std::uint8_t>& out, std::string_view s) {
  put(out, static_cast<std::uint32_t>(s.size()));
  out.insert(out.end(), s.begin(), s.end());
}

inline void put_map(std::vector<std::uint8_t>& out, const KeyValueMap& m) {
  std::uint64_t bytes = 0;
  for (const auto& [k, v] : m) bytes += 8 + k.size() + v.size();
  put(out, static_cast<std::uint32_t>(bytes));
  for (const auto& [k, v] : m) {
    put_string(out, k);
    put_string(out, v);
  }
}

/// Starts a record: opcode and a length placeholder; returns the position to patch.
inline std::size_t begin_record(std::vector<std::uint8_t>& out, Opcode op) {
  out.push_back(static_cast<std::uint8_t>(op));
  const auto pos = out.size();
  put<std::uint64_t>(out, 0);
  return pos;
}

inline void end_record(std::vector<std::uint8_t>& out, std::size_t len_pos) {
  const std::uint64_t len = out.size() - len_pos - 8;
  std::memcpy(out.data() + len_pos, &len, 8);
}

template <class T>
inline T load(const std::uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

/// Bounded field reader over one record's content. Every getter checks the
/// bytes left; the first failure is kept and later getters return defaults.
class Cursor {
 public:
  Cursor(std::span<const std::uint8_t> content, std::string_view where) : data_(content), where_(where) {}

  template <class T>
  T get(const char* field) {
    if (!need(sizeof(T), field)) return T{};
    T v = load<T>(data_.data() + pos_);
    pos_ += sizeof(T);
    return v;
  }

  std::string get_string(const char* field) {
    const auto n = get<std::uint32_t>(field);
    if (!need(n, field)) return {};
    std::string s(reinterpret_cast<const char*>(data_.data() + pos_), n);
    pos_ += n;
    return s;
  }

  std::span<const std::uint8_t> get_bytes(std::uint64_t n, const char* field) {
    if (!need(n, field)) return {};
    auto s = data_.subspan(pos_, static_cast<std::size_t>(n));
    pos_ += static_cast<std::size_t>(n);
    return s;
  }

  /// A u32 byte-length-prefixed array: returns its bytes.
  std::span<const std::uint8_t> get_prefixed32(const char* field) {
    const auto n = get<std::uint32_t>(field);
    return get_bytes(n, field);
  }

  KeyValueMap get_map(const char* field) {
    KeyValueMap m;
    auto bytes = get_prefixed32(field);
    if (!ok()) return m;
    Cursor inner(bytes, where_);
    while (inner.ok() && inner.remaining() > 0) {
      std::string k = inner.get_string(field);
      std::string v = inner.get_string(field);
      if (inner.ok()) m[std::move(k)] = std::move(v);
    }
    if (!inner.ok()) status_ = inner.status_;
    return m;
  }

  std::span<const std::uint8_t> rest() { return data_.subspan(std::min(pos_, data_.size())); }
  std::size_t remaining() const { return pos_ >= data_.size() ? 0 : data_.size() - pos_; }
  std::size_t position() const { return pos_; }
  bool ok() const { return status_.ok(); }
  Status status() const { return status_; }
  void fail(std::string what) {
    if (ok()) status_ = Status(StatusCode::InvalidRecord, fmt::format("{}: {}", where_, what));
  }

 private:
  bool need(std::uint64_t n, const char* field) {
    if (!ok()) return false;
    if (n > remaining()) {
      status_ =
          Status(StatusCode::InvalidRecord, fmt::format("{}: field '{}' at content byte {} needs {} bytes, {} left",
                                                        where_, field, pos_, n, remaining()));
      return false;
    }
    return true;
  }

  std::span<const std::uint8_t> data_;
  std::size_t pos_ = 0;
  std::string_view where_;
  Status status_;
};

/// Parses with no context first and, only if that fails, again with the
/// context string from `where()`: building "file: record at byte N" for every
/// record would cost more than parsing it.
template <class R, class W>
Status parse_lazy(std::span<const std::uint8_t> content, R& out, const W& where) {
  Status s = parse(content, out, std::string_view{});
  if (!s.ok()) s = parse(content, out, where());
  return s;
}

}  // namespace tinyline::bag::wire
