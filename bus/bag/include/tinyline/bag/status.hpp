// SPDX-License-Identifier: Apache-2.0
// Status of bag I/O: every failure says what went wrong and where (file and
// byte offset). The codec returns Status; code that prefers exceptions wraps it
// in BagError.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>

namespace tinyline::bag {

enum class StatusCode {
  Ok = 0,
  OpenFailed,        ///< the file could not be opened or created
  ReadFailed,        ///< an I/O error while reading
  WriteFailed,       ///< an I/O error while writing (disk full, closed fd)
  BadMagic,          ///< the leading or trailing magic bytes are wrong
  Truncated,         ///< the file ends inside a record (a writer that died, or a cut copy)
  InvalidRecord,     ///< a record's content does not parse
  InvalidFooter,     ///< the footer or summary offsets point outside the file
  CrcMismatch,       ///< a chunk, data section, summary or attachment CRC does not match
  Unsupported,       ///< an unknown chunk compression, or a feature this reader lacks
  DecompressFailed,  ///< the compressed bytes of a chunk are corrupt
  LimitExceeded,     ///< a record is larger than the reader's configured limit
  InvalidArgument,   ///< the caller asked for something impossible (unknown channel, ...)
  NotOpen,           ///< the reader or writer is not open (or already closed)
};

std::string_view to_string(StatusCode c);

struct [[nodiscard]] Status {
  StatusCode code = StatusCode::Ok;
  std::string message;

  Status() = default;
  Status(StatusCode c, std::string m) : code(c), message(std::move(m)) {}

  static Status ok_status() { return {}; }
  bool ok() const { return code == StatusCode::Ok; }
  explicit operator bool() const { return ok(); }
  /// "crc mismatch: scans.mcap: chunk at byte 1234: ..."
  std::string str() const;
};

class BagError : public std::runtime_error {
 public:
  explicit BagError(Status s) : std::runtime_error(s.str()), status_(std::move(s)) {}
  const Status& status() const { return status_; }

 private:
  Status status_;
};

/// Throws BagError unless `s` is ok. For code where a failure is fatal anyway.
inline void throw_if_error(Status s) {
  if (!s.ok()) throw BagError(std::move(s));
}

}  // namespace tinyline::bag
