// SPDX-License-Identifier: Apache-2.0
// A tinyline "process" inside a test: a context logging to a capture sink,
// its DDS bridge with every topic selected, one node to publish and subscribe
// from, and an executor on two threads once run() is called. For tests that
// talk to another DDS implementation (test/dds/interop_test.cpp,
// test/ros2/ros2_test.cpp).
#pragma once

#include <memory>
#include <string>
#include <thread>

#include <tinyline/bus/executor.hpp>
#include <tinyline/bus/node.hpp>
#include <tinyline/dds/bridge.hpp>

#include "../../bus/dds/test/waiting.hpp"

namespace tinyline::testing {

struct BridgedGraph {
  std::shared_ptr<Signal> signal = std::make_shared<Signal>();
  std::shared_ptr<SignallingSink> sink = std::make_shared<SignallingSink>(signal);
  std::shared_ptr<bus::Context> ctx;
  std::shared_ptr<dds::Bridge> bridge;
  std::shared_ptr<bus::Node> node;
  std::unique_ptr<bus::MultiThreadedExecutor> ex;
  std::thread spinner;

  BridgedGraph(const dds::Settings& settings, const std::string& node_name) {
    bus::ContextOptions co;
    co.log_sink = sink;
    ctx = bus::Context::create(co);
    dds::BridgeOptions bo;
    bo.settings = settings;
    bo.selection.all = true;
    bridge = dds::Bridge::create(ctx, bo);
    bus::NodeOptions no;
    no.name = node_name;
    no.context = ctx;
    node = std::make_shared<bus::Node>(no);
  }
  BridgedGraph(const BridgedGraph&) = delete;
  BridgedGraph& operator=(const BridgedGraph&) = delete;
  void run() {
    bridge->start();
    ex = std::make_unique<bus::MultiThreadedExecutor>(ctx->clock(), 2);
    ex->add_node(bridge);
    ex->add_node(node);
    spinner = std::thread([this] { ex->spin(); });
  }
  /// Waits until the log has a record of `level` containing `text`.
  bool logged(bus::LogLevel level, const std::string& text, std::chrono::milliseconds timeout) {
    return signal->wait_for([&] { return sink->contains(level, text); }, timeout);
  }
  ~BridgedGraph() {
    if (ex) ex->stop();
    if (spinner.joinable()) spinner.join();
  }
};

}  // namespace tinyline::testing
