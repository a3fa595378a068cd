// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bag/register.hpp>

#include <tinyline/bag/player.hpp>
#include <tinyline/bag/recorder.hpp>

namespace tinyline::bag {

void register_nodes(bus::NodeRegistry& registry) {
  registry.add<Recorder>("bag", "recorder", "records topics (all by default) to an MCAP bag");
  registry.add<Player>("bag", "player", "plays an MCAP bag onto the bus, optionally driving /clock");
}

}  // namespace tinyline::bag
