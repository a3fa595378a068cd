// SPDX-License-Identifier: Apache-2.0
// What travels with a message inside the process.
#pragma once

#include <cstdint>
#include <memory>

#include <tinyline/bus/time.hpp>

namespace tinyline::bus {

/// What a subscriber learns about a message besides its content.
struct MessageInfo {
  Time publish_time;           ///< context clock at publish
  std::uint64_t sequence = 0;  ///< per-topic publish counter, from 1
  std::uint32_t origin = 0;    ///< 0: published in this process; else the transport that brought it
};

/// One queued message: the shared object and its info.
struct QueuedMessage {
  std::shared_ptr<const void> msg;
  MessageInfo info;
};

}  // namespace tinyline::bus
