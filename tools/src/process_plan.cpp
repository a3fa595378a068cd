// SPDX-License-Identifier: Apache-2.0
#include "process_plan.hpp"

#include <algorithm>
#include <map>
#include <set>

#include <fmt/format.h>

namespace tinyline::tools {

const ProcessPlan* GraphPlan::find(const std::string& name) const {
  for (const auto& p : processes)
    if (p.name == name) return &p;
  return nullptr;
}

namespace {

struct Use {
  std::vector<bus::QoS> pubs;
  std::vector<bus::QoS> subs;
  std::string type;
};
using TopicUses = std::map<std::string, Use>;  // topic -> endpoints in one process

std::string describe_process(const ProcessPlan& p) {
  return p.name.empty() ? "the launching process" : "process '" + p.name + "'";
}

// Builds the process's nodes in a scratch context and configures them (their
// input files load), noting their endpoints, the topics they want without an
// endpoint yet (a recorder's topics) and the topics marked for DDS.
std::vector<std::shared_ptr<bus::Node>> build_process(ProcessPlan& pp, const launch::LaunchPlan& plan,
                                                      const bus::NodeRegistry& registry, TopicUses& uses,
                                                      std::vector<std::string>& wants) {
  bus::ContextOptions co;
  co.clock = bus::ClockType::Sim;
  co.log_sink = std::make_shared<bus::CaptureSink>();
  const auto ctx = bus::Context::create(co);
  auto nodes = launch::instantiate(plan, registry, ctx, pp.name);
  wants = ctx->graph().wants();
  launch::configure(plan, nodes, pp.name);
  std::set<std::string> marked;
  for (const auto& spec : plan.nodes) {
    if (spec.process != pp.name) continue;
    pp.respawn |= spec.respawn;
    if (spec.dds) marked.insert((spec.ns == "/" ? "" : spec.ns) + "/" + spec.name);
  }
  for (const auto& n : nodes) {
    pp.nodes.push_back(n->full_name());
    const auto info = n->describe();
    for (const auto& e : info.publishers) {
      uses[e.topic].pubs.push_back(e.qos);
      pp.publishes.insert(e.topic);
      pp.uses.insert(e.topic);
    }
    for (const auto& e : info.subscriptions) {
      uses[e.topic].subs.push_back(e.qos);
      pp.uses.insert(e.topic);
    }
    for (const auto* list : {&info.publishers, &info.subscriptions})
      for (const auto& e : *list) uses[e.topic].type = e.type;
    if (marked.count(n->full_name()) != 0) {
      for (const auto* list : {&info.publishers, &info.subscriptions})
        for (const auto& e : *list) pp.dds.topics.push_back(e.topic);
    }
  }
  pp.dds.all = plan.dds.all;
  pp.dds.topics.insert(pp.dds.topics.end(), plan.dds.topics.begin(), plan.dds.topics.end());
  return nodes;
}

// A topic has one type in the whole graph. Within a process the bus refuses
// a second one; across processes DDS would just never connect the two, so
// the file is refused here, naming both.
void check_types(const GraphPlan& g, const std::vector<TopicUses>& uses) {
  for (std::size_t p = 0; p < g.processes.size(); ++p) {
    for (const auto& [topic, mine] : uses[p]) {
      for (std::size_t q = p + 1; q < g.processes.size(); ++q) {
        const auto it = uses[q].find(topic);
        if (it == uses[q].end() || it->second.type == mine.type) continue;
        throw launch::LaunchError({}, fmt::format("topic {} has type {} in {} and {} in {}: a topic has one type "
                                                  "(over DDS the two would never connect)",
                                                  topic, mine.type, describe_process(g.processes[p]), it->second.type,
                                                  describe_process(g.processes[q])));
      }
    }
  }
}

// A topic a node wants in one process (a recorder's topics) and another
// process publishes travels over DDS in both: the wanting process learns its
// type from the publisher's DDS endpoint.
void share_wanted_topics(GraphPlan& g, const std::vector<TopicUses>& uses,
                         const std::vector<std::vector<std::string>>& wants) {
  for (std::size_t p = 0; p < g.processes.size(); ++p) {
    for (const auto& topic : wants[p]) {
      if (uses[p].count(topic) != 0) continue;
      for (std::size_t q = 0; q < g.processes.size(); ++q) {
        const auto it = uses[q].find(topic);
        if (q == p || it == uses[q].end() || it->second.pubs.empty()) continue;
        g.processes[p].dds.topics.push_back(topic);
        g.processes[q].dds.topics.push_back(topic);
      }
    }
  }
}

// Topics that cross processes travel over DDS wherever they are used.
void share_crossing_topics(GraphPlan& g, const std::vector<TopicUses>& uses) {
  for (std::size_t p = 0; p < g.processes.size(); ++p) {
    for (const auto& [topic, use] : uses[p]) {
      for (std::size_t q = 0; q < g.processes.size(); ++q) {
        if (q != p && uses[q].count(topic) != 0) g.processes[p].dds.topics.push_back(topic);
      }
    }
  }
  for (auto& pp : g.processes) {
    std::sort(pp.dds.topics.begin(), pp.dds.topics.end());
    pp.dds.topics.erase(std::unique(pp.dds.topics.begin(), pp.dds.topics.end()), pp.dds.topics.end());
  }
}

// The remote endpoints process `p` waits for on `topic`, and the pairs DDS
// will refuse to connect (warnings).
dds::PeerExpectation expect_on(GraphPlan& g, const std::vector<TopicUses>& uses, std::size_t p,
                               const std::string& topic, const Use& mine) {
  dds::PeerExpectation e{topic, 0, 0};
  for (std::size_t q = 0; q < g.processes.size(); ++q) {
    if (q == p || !g.processes[q].dds.selects(topic)) continue;
    const auto it = uses[q].find(topic);
    if (it == uses[q].end()) continue;
    const Use& theirs = it->second;
    if (!mine.pubs.empty() && !theirs.subs.empty()) {
      const auto why = dds::incompatibility(dds::offered_qos(mine.pubs), dds::requested_qos(theirs.subs));
      if (why.empty()) {
        ++e.readers;
      } else {
        g.warnings.push_back(fmt::format("{}: DDS will not connect the publishers in {} to the subscribers in {}: {}",
                                         topic, describe_process(g.processes[p]), describe_process(g.processes[q]),
                                         why));
      }
    }
    if (!mine.subs.empty() && !theirs.pubs.empty() &&
        dds::incompatibility(dds::offered_qos(theirs.pubs), dds::requested_qos(mine.subs)).empty()) {
      ++e.writers;
    }
  }
  return e;
}

}  // namespace

GraphPlan plan_processes(const launch::LaunchPlan& plan, const bus::NodeRegistry& registry) {
  GraphPlan g;
  g.processes.push_back(ProcessPlan{});
  for (const auto& n : plan.nodes) {
    if (g.find(n.process) == nullptr) g.processes.push_back(ProcessPlan{n.process, {}, false, {}, {}, {}, {}});
  }
  std::vector<TopicUses> uses(g.processes.size());
  std::vector<std::vector<std::string>> wants(g.processes.size());
  std::vector<std::shared_ptr<bus::Node>> all;  // every node once: files are checked across processes
  for (std::size_t p = 0; p < g.processes.size(); ++p) {
    for (auto& n : build_process(g.processes[p], plan, registry, uses[p], wants[p])) all.push_back(std::move(n));
  }
  launch::check_files(all);
  check_types(g, uses);
  share_wanted_topics(g, uses, wants);
  share_crossing_topics(g, uses);
  for (std::size_t p = 0; p < g.processes.size(); ++p) {
    for (const auto& [topic, mine] : uses[p]) {
      if (!g.processes[p].dds.selects(topic)) continue;
      const dds::PeerExpectation e = expect_on(g, uses, p, topic, mine);
      if (e.readers + e.writers > 0) g.processes[p].expect.push_back(e);
    }
  }
  return g;
}

dds::Settings dds_settings(const launch::LaunchPlan& plan, const std::string& process_name) {
  dds::Settings s = dds::Settings::from_environment();
  if (plan.dds.domain_id) s.domain_id = *plan.dds.domain_id;
  if (!plan.dds.config.empty()) s.config = plan.dds.config;
  s.shared_memory = s.shared_memory || plan.dds.shared_memory;
  s.process_name = process_name;
  return s;
}

}  // namespace tinyline::tools
