// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bag/status.hpp>

namespace tinyline::bag {

std::string_view to_string(StatusCode c) {
  switch (c) {
    case StatusCode::Ok: return "ok";
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
    case StatusCode::InvalidArgument: return "invalid argument";
    case StatusCode::NotOpen: return "not open";
  }
  return "unknown status";
}

std::string Status::str() const {
  if (ok()) return "ok";
  return std::string(to_string(code)) + ": " + message;
}

}  // namespace tinyline::bag
