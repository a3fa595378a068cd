// SPDX-License-Identifier: Apache-2.0
// Uses an installed tinyline: parses a sensor frame with the core library and
// runs a registered node on the bus for a few sim-time steps.
#include <cstdio>
#include <filesystem>

#include <tiny_laser_driver/protocol.hpp>
#include <tinyline/bus/executor.hpp>
#include <tinyline/launch/launch.hpp>
#include <tinyline/msg/std_msgs/string.hpp>
#include <tinyline/tools/nodes.hpp>

using namespace tinyline;

int main(int argc, char** argv) {
  // Core: the wire protocol, no bus.
  tiny_laser_driver::DistanceFrame f;
  f.distance[10] = 1234;
  std::vector<std::uint8_t> bytes;
  tiny_laser_driver::encode_distance_frame(f, bytes);
  tiny_laser_driver::Parser p;
  p.feed(bytes);
  auto got = p.next_distance();
  if (!got || got->distance[10] != 1234) return std::puts("downstream: protocol failed"), 1;

  // Nodes: a registered node type built from a launch description.
  bus::NodeRegistry reg;
  tools::register_nodes(reg);
  bus::ContextOptions co;
  co.clock = bus::ClockType::Sim;
  auto ctx = bus::Context::create(co);
  auto plan = launch::load_launch_string(
      "launch:\n- node: {pkg: tinyline, exec: pulse, param: [{name: rate_hz, value: 10.0}]}\n", "inline");
  auto nodes = launch::instantiate(plan, reg, ctx);
  auto me = std::make_shared<bus::Node>(bus::NodeOptions{"me", "/", {}, {}, ctx, "", {}});
  int heard = 0;
  auto sub = me->create_subscription<std_msgs::msg::String>("/output", bus::QoS::keep_last(10),
                                                            [&](const std_msgs::msg::String&) { ++heard; });
  bus::DeterministicExecutor ex(ctx->clock());
  for (auto& n : nodes) ex.add_node(n);
  ex.add_node(me);
  ex.advance_to(bus::Time::from_seconds(1.0));
  ex.advance_to(bus::Time::from_seconds(2.0));
  if (heard != 10) return std::printf("downstream: heard %d pulses, expected 10\n", heard), 1;
  if (argc > 1 && !std::filesystem::exists(std::filesystem::path(argv[1]) / "share/tinyline/launch")) {
    return std::puts("downstream: launch files were not installed"), 1;
  }
  std::puts("downstream: ok");
  return 0;
}
