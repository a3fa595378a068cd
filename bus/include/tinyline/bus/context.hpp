// SPDX-License-Identifier: Apache-2.0
// A context: one graph, one clock and one log sink shared by the nodes of a
// process (or of a test). Nodes of different contexts never see each other.
#pragma once

#include <memory>

#include <tinyline/bus/clock.hpp>
#include <tinyline/bus/graph.hpp>
#include <tinyline/bus/logging.hpp>

namespace tinyline::bus {

struct ContextOptions {
  ClockType clock = ClockType::Wall;
  std::shared_ptr<LogSink> log_sink;  ///< default: stderr
};

class Context {
 public:
  static std::shared_ptr<Context> create(ContextOptions options = {});
  explicit Context(ContextOptions options);
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  Graph& graph() { return graph_; }
  const Graph& graph() const { return graph_; }
  Clock& clock() { return clock_; }
  const std::shared_ptr<LogSink>& log_sink() const { return log_sink_; }
  Logger logger(std::string name) const { return Logger(std::move(name), log_sink_, &clock_); }

 private:
  Clock clock_;
  Graph graph_;
  std::shared_ptr<LogSink> log_sink_;
};

}  // namespace tinyline::bus
