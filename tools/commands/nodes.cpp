// tinyline nodes | tinyline describe PKG/TYPE
#include <fmt/format.h>

#include <tinyline/tools/command.hpp>

#include "../src/cli.hpp"

namespace tinyline::tools {
namespace {

CommandRun setup_nodes(CLI::App& cmd) {
  cmd.footer("Lists every registered node type (what a launch file's pkg/exec can name).");
  return [] {
    for (const auto* t : node_registry().all()) fmt::print("{:<40} {}\n", t->full_name(), t->description);
    return 0;
  };
}

int describe(const std::string& full) {
  const auto slash = full.find('/');
  if (slash == std::string::npos) throw UsageError("expected PKG/TYPE, got '" + full + "'");
  bus::ContextOptions co;
  co.clock = bus::ClockType::Sim;
  auto sink = std::make_shared<bus::CaptureSink>();
  co.log_sink = sink;
  auto ctx = bus::Context::create(co);
  bus::NodeOptions o;
  o.context = ctx;
  o.name = full.substr(slash + 1);
  std::shared_ptr<bus::Node> n;
  try {
    n = node_registry().create(full.substr(0, slash), full.substr(slash + 1), o);
  } catch (const bus::ParamError& e) {
    fmt::print(stderr, "{}\n", e.what());
    return 1;
  }
  const auto* info = node_registry().find(full.substr(0, slash), full.substr(slash + 1));
  fmt::print("{}: {}\n\nparameters:\n", full, info->description);
  for (const auto& p : n->parameters()) {
    std::string range;
    if (p.constraints.min) range += fmt::format(" min {}", *p.constraints.min);
    if (p.constraints.max) range += fmt::format(" max {}", *p.constraints.max);
    if (!p.constraints.choices.empty()) {
      range += " one of";
      for (const auto& c : p.constraints.choices) range += " " + c;
    }
    fmt::print("  {:<24} {:<13} default {}{}\n      {}\n", p.name, bus::to_string(p.type),
               bus::format_value(p.default_value), range.empty() ? "" : " (" + range.substr(1) + ")", p.description);
  }
  const auto d = n->describe();
  fmt::print("\npublishes:\n");
  for (const auto& e : d.publishers) fmt::print("  {:<30} {:<36} {}\n", e.topic, e.type, e.qos.describe());
  fmt::print("\nsubscribes:\n");
  for (const auto& e : d.subscriptions) fmt::print("  {:<30} {:<36} {}\n", e.topic, e.type, e.qos.describe());
  return 0;
}

CommandRun setup_describe(CLI::App& cmd) {
  auto type = std::make_shared<std::string>();
  cmd.add_option("type", *type, "the node type, PKG/TYPE (tinyline nodes lists them)")->required();
  cmd.footer("Shows a node type's parameters (type, default, range, description) and its topics with types and QoS.");
  return [type] { return describe(*type); };
}

const CommandRegistration kNodes{"nodes", "list registered node types", &setup_nodes};
const CommandRegistration kDescribe{"describe", "show a node type's parameters and topics", &setup_describe};

}  // namespace
}  // namespace tinyline::tools
