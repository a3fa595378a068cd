// SPDX-License-Identifier: Apache-2.0
// Status of bag I/O: every failure says what went wrong and where (file and
// byte offset). The codec returns Status; code that prefers exceptions wraps it
// in BagError.
#pragma once

#include <stdexcept>
#include <utility>

#include <tinyline/common/status.hpp>

namespace tinyline::bag {

/// The bag codec's outcome is the project's one outcome type; its codes for
/// files and streams (OpenFailed ... NotOpen) live there with the others.
using common::Status;
using common::StatusCode;
using common::to_string;

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
