// SPDX-License-Identifier: Apache-2.0
// The one outcome of a core function: a code and a message. A function that
// can fail returns a Status, or a result struct that holds `Status status`
// beside its value; a parameter check (validate(params), within_table) returns
// one whose message names the parameter and the rule it breaks ("eps_m must
// be in [0.0001, 2], got -1"). A constructor that cannot work with its
// settings throws std::invalid_argument with that message (set-up); a node
// turns a failed check into the bus's ParamError with its own name.
#pragma once

#include <string>
#include <string_view>
#include <utility>

namespace tinyline::common {

/// What kind of failure. Only codes some caller tells apart.
enum class StatusCode {
  Ok = 0,
  InvalidArgument,  ///< the caller's parameters or input break a rule (the message names it)
  OutOfRange,       ///< a lookup outside what is held (a time before the first pose)
  NotFound,         ///< valid input in which the thing sought is not there (no cluster, no circle)
  // Files and streams (the bag codec).
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
  NotOpen,           ///< the reader or writer is not open (or already closed)
};

[[nodiscard]] constexpr std::string_view to_string(StatusCode c) {
  switch (c) {
    case StatusCode::Ok: return "ok";
    case StatusCode::InvalidArgument: return "invalid argument";
    case StatusCode::OutOfRange: return "out of range";
    case StatusCode::NotFound: return "not found";
    case StatusCode::OpenFailed: return "open failed";
    case StatusCode::ReadFailed: return "read failed";
    case StatusCode::WriteFailed: return "write failed";
    case StatusCode::BadMagic: return "bad magic";
    case StatusCode::Truncated: return "truncated";
    case StatusCode::InvalidRecord: return "invalid record";
    case StatusCode::InvalidFooter: return "invalid footer";
    case StatusCode::CrcMismatch: return "crc mismatch";
    case StatusCode::Unsupported: return "unsupported";
    case StatusCode::DecompressFailed: return "decompression failed";
    case StatusCode::LimitExceeded: return "limit exceeded";
    case StatusCode::NotOpen: return "not open";
  }
  return "unknown status";
}

struct Validation;

struct [[nodiscard]] Status {
  StatusCode code = StatusCode::Ok;
  /// What went wrong and where; empty when ok.
  std::string message;

  Status() = default;
  Status(StatusCode c, std::string m) : code(c), message(std::move(m)) {}

  [[nodiscard]] static Status ok_status() { return {}; }
  [[nodiscard]] static Status invalid(std::string m) { return {StatusCode::InvalidArgument, std::move(m)}; }
  [[nodiscard]] static Status not_found(std::string m) { return {StatusCode::NotFound, std::move(m)}; }

  [[nodiscard]] bool ok() const { return code == StatusCode::Ok; }
  explicit operator bool() const { return ok(); }
  /// "crc mismatch: scans.mcap: chunk at byte 1234: ..."; "ok" when ok.
  [[nodiscard]] std::string str() const { return ok() ? "ok" : std::string(to_string(code)) + ": " + message; }

  /// The same outcome with the message prefixed by where it comes from, for
  /// a nested parameter struct: validate(p.dbscan).within("dbscan") reads
  /// "dbscan: eps must be > 0".
  [[nodiscard]] Status within(std::string_view what) const {
    if (ok()) return *this;
    return {code, std::string(what) + ": " + message};
  }

  /// The older {valid, reason} form, while its last users move to Status.
  operator Validation() const;  // NOLINT(google-explicit-constructor)
};

/// The older form of a parameter check's outcome, {valid, reason}. Being
/// replaced by Status; it converts both ways (an invalid one is an
/// InvalidArgument) so that the packages still using it build beside those
/// that moved. New code returns Status.
struct [[nodiscard]] Validation {
  bool valid = true;
  /// Why not valid; empty when valid.
  std::string reason;

  [[nodiscard]] static Validation ok() { return {}; }
  [[nodiscard]] static Validation invalid(std::string reason) { return {false, std::move(reason)}; }
  [[nodiscard]] Validation within(std::string_view what) const {
    if (valid) return *this;
    return {false, std::string(what) + ": " + reason};
  }
  operator Status() const {  // NOLINT(google-explicit-constructor)
    return valid ? Status{} : Status::invalid(reason);
  }
};

inline Status::operator Validation() const { return ok() ? Validation{} : Validation{false, message}; }

}  // namespace tinyline::common

namespace tinyline {
using common::Status;
using common::StatusCode;
}  // namespace tinyline
