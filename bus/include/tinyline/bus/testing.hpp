// SPDX-License-Identifier: Apache-2.0
// Test support for node tests: a graph on sim time that a test steps.
//
//   tinyline::bus::testing::NodeRig rig({&my_pkg::register_nodes});
//   auto& fits = rig.collect<CircleFit>("circle");          // every message on "circle"
//   bus::NodeOptions o;
//   o.name = "fitter";
//   rig.add("my_pkg", "circle_fitter", o);
//   auto pub = rig.io->create_publisher<LineScan>("scan", bus::QoS::keep_last(10));
//   pub->publish(std::move(scan));
//   rig.ex.advance_to(bus::Time::from_seconds(1.0));      // no sleeps: time is stepped
//   EXPECT_EQ(fits.size(), 1u);
//   EXPECT_TRUE(rig.log->contains(bus::LogLevel::Warn, "..."));
//
// Also TempDir, a directory a test writes into and that is gone after it.
// Header-only and free of gtest so a user's own test framework can use it.
#pragma once

#include <stdlib.h>

#include <filesystem>
#include <initializer_list>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "tinyline/bus/context.hpp"
#include "tinyline/bus/executor.hpp"
#include "tinyline/bus/logging.hpp"
#include "tinyline/bus/node.hpp"
#include "tinyline/bus/registry.hpp"

namespace tinyline::bus::testing {

/// A fresh directory under /tmp for one test, removed with everything in it
/// when the test ends.
struct TempDir {
  std::filesystem::path path;
  TempDir() {
    char tmpl[] = "/tmp/tinyline_test_XXXXXX";
    const char* made = ::mkdtemp(tmpl);
    if (made == nullptr) throw std::runtime_error("cannot make a temporary directory under /tmp");
    path = made;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  /// The path of a file in the directory, as a string (for argv-style lists).
  std::string operator/(const std::string& file) const { return (path / file).string(); }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
};

/// A sim-clock context whose log goes to a CaptureSink, a DeterministicExecutor
/// on its clock, a NodeRegistry, and an "io" node the test publishes from and
/// listens on. Members are public: tests use them directly.
class NodeRig {
 public:
  using Registration = void (*)(NodeRegistry&);

  /// Registers the node types of each package given (their register_nodes).
  /// With `start`, sim time starts there; without, the clock stays unstarted
  /// (as ROS's sim time before the first /clock) until the test steps it.
  NodeRig(std::initializer_list<Registration> registrations = {}, std::optional<Time> start = std::nullopt)
      : ctx(make_context(log)), ex(ctx->clock()) {
    for (Registration r : registrations) r(registry);
    if (start) ctx->clock().set_sim_time(*start);
    NodeOptions o;
    o.name = "io";
    o.context = ctx;
    io = std::make_shared<Node>(o);
    ex.add_node(io);
  }

  NodeRig(const NodeRig&) = delete;
  NodeRig& operator=(const NodeRig&) = delete;

  /// Creates a registered node `package/type` in this graph and adds it to the
  /// executor. Throws (from the registry) for an unknown type or bad parameters.
  std::shared_ptr<Node> add(const std::string& package, const std::string& type, NodeOptions o) {
    o.context = ctx;
    auto n = registry.create(package, type, std::move(o));
    ex.add_node(n);
    return n;
  }

  /// Adds a node the test built itself (its options must use `ctx`).
  template <class N>
  std::shared_ptr<N> add(std::shared_ptr<N> n) {
    ex.add_node(n);
    return n;
  }

  /// Keeps every message published on `topic` from now on, in arrival order.
  /// The vector lives as long as the rig.
  template <class M>
  std::vector<std::shared_ptr<const M>>& collect(const std::string& topic, QoS qos = QoS::keep_last(10000)) {
    auto c = std::make_shared<Collected<M>>();
    Collected<M>* raw = c.get();
    c->sub = io->create_subscription<M>(topic, qos,
                                        [raw](const std::shared_ptr<const M>& m) { raw->messages.push_back(m); });
    keep_.push_back(c);
    return raw->messages;
  }

  // Declaration order is construction order: the sink before the context that
  // logs to it, the context before the executor on its clock.
  std::shared_ptr<CaptureSink> log = std::make_shared<CaptureSink>();
  std::shared_ptr<Context> ctx;
  DeterministicExecutor ex;
  NodeRegistry registry;
  std::shared_ptr<Node> io;

 private:
  template <class M>
  struct Collected {
    std::vector<std::shared_ptr<const M>> messages;
    std::shared_ptr<Subscription<M>> sub;
  };

  static std::shared_ptr<Context> make_context(std::shared_ptr<CaptureSink> sink) {
    ContextOptions o;
    o.clock = ClockType::Sim;
    o.log_sink = std::move(sink);
    return Context::create(o);
  }

  std::vector<std::shared_ptr<void>> keep_;  // the collectors' vectors and subscriptions
};

}  // namespace tinyline::bus::testing
