// SPDX-License-Identifier: Apache-2.0
// How a launch file splits into processes, and what each process puts on DDS.
//
// Every node of every process group is built once in a scratch context (so a
// bad parameter anywhere stops the launch before anything starts), and their
// topics decide the rest:
//   - a topic with endpoints in two or more processes travels over DDS in each
//     of them (the graph keeps working when split);
//   - topics the file marks (dds: on a node or group, a top-level dds action)
//     travel over DDS too, for tinyline topic and ROS 2 nodes;
//   - each process waits, before its nodes start, until the DDS endpoints of
//     the processes it talks to are matched, so no first message is lost to
//     discovery.
#pragma once

#include <set>
#include <string>
#include <vector>

#include <tinyline/bus/registry.hpp>
#include <tinyline/dds/bridge.hpp>
#include <tinyline/launch/launch.hpp>

namespace tinyline::tools {

struct ProcessPlan {
  std::string name;                          ///< "" for the launching process
  std::vector<std::string> nodes;            ///< full names of its nodes
  bool respawn = false;                      ///< some node asks to be restarted
  dds::TopicSelection dds;                   ///< topics this process puts on DDS
  std::vector<dds::PeerExpectation> expect;  ///< remote endpoints to wait for
  std::set<std::string> publishes;           ///< topics its nodes publish
  std::set<std::string> uses;                ///< topics its nodes publish or subscribe
  bool uses_dds() const { return dds.all || !dds.topics.empty(); }
};

struct GraphPlan {
  std::vector<ProcessPlan> processes;  ///< the launching process ("") first, even without nodes
  std::vector<std::string> warnings;   ///< QoS that DDS will not connect across processes
  const ProcessPlan* find(const std::string& name) const;
  bool has_groups() const { return processes.size() > 1; }
};

/// Builds and configures every node once (launch::configure) and checks the
/// files they name (launch::check_files). Throws launch::LaunchError (the
/// first node that cannot be built, or an input that is unusable).
GraphPlan plan_processes(const launch::LaunchPlan& plan, const bus::NodeRegistry& registry);

/// ROS_DOMAIN_ID / CYCLONEDDS_URI, overridden by the file's dds action.
dds::Settings dds_settings(const launch::LaunchPlan& plan, const std::string& process_name);

}  // namespace tinyline::tools
