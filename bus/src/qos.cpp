// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bus/qos.hpp>

#include <fmt/format.h>

namespace tinyline::bus {

std::string QoS::describe() const {
  std::string s = history == History::KeepLast ? fmt::format("keep_last({})", depth)
                                               : fmt::format("reliable({}, {:.3f} s)", depth, to_seconds(max_block));
  if (transient_local) s += ", latched";
  if (best_effort) s += ", best_effort";
  return s;
}

}  // namespace tinyline::bus
