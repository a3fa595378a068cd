// SPDX-License-Identifier: Apache-2.0
// The one way a core says "these parameters are invalid": validate(params)
// returns a Validation, {valid, reason}, where the reason names the parameter
// and the rule it breaks ("eps must be > 0, got -1"). A core function given
// invalid parameters returns a result carrying the reason; a constructor that
// cannot work with them throws std::invalid_argument with it (set-up); a
// node turns an invalid one into the bus's ParamError with its own name.
#pragma once

#include <string>
#include <string_view>
#include <utility>

namespace tinyline::common {

struct [[nodiscard]] Validation {
  bool valid = true;
  /// Why not valid; empty when valid.
  std::string reason;

  [[nodiscard]] static Validation ok() { return {}; }
  [[nodiscard]] static Validation invalid(std::string reason) { return {false, std::move(reason)}; }

  /// The same verdict with the reason prefixed by where it comes from, for a
  /// nested parameter struct: validate(p.dbscan).within("dbscan") reads
  /// "dbscan: eps must be > 0".
  [[nodiscard]] Validation within(std::string_view what) const {
    if (valid) return *this;
    return {false, std::string(what) + ": " + reason};
  }
};

}  // namespace tinyline::common
