// SPDX-License-Identifier: Apache-2.0
// tinyline run PKG TYPE (or PKG/TYPE, as `tinyline describe` names it) [-p name:=value] [-r from:=to] [--name N] [--ns NS] [--duration S]
#include <memory>

#include <fmt/format.h>

#include <tinyline/dds/bridge.hpp>
#include <tinyline/tools/command.hpp>

#include "../src/parsing.hpp"
#include "../src/graph_runner.hpp"

namespace tinyline::tools {
namespace {

struct RunArgs {
  std::string pkg;
  std::string type;
  std::vector<std::string> params;  // name:=value
  std::vector<std::string> remaps;  // from:=to
  std::string name;
  std::string ns = "/";
  std::optional<double> duration_s;
  int threads = 1;
  bool no_table = false;
  bool dds = false;
};

bus::NodeOptions node_options(const RunArgs& a, const std::shared_ptr<bus::Context>& ctx) {
  bus::NodeOptions o;
  o.context = ctx;
  o.name = a.name.empty() ? a.type : a.name;
  o.ns = a.ns;
  o.where = bus::SourceLocation{"command line", 0, 0};
  for (const auto& p : a.params) {
    auto [k, v] = parsing::split_assignment(p);
    o.params.push_back({k, bus::parse_param_text(v), bus::SourceLocation{"command line (-p " + p + ")", 0, 0}});
  }
  for (const auto& r : a.remaps) {
    auto [from, to] = parsing::split_assignment(r);
    o.remaps.push_back({from, to});
  }
  return o;
}

// `run tinyline/pulse` names the type as `nodes` and `describe` print it.
bool split_pkg_type(RunArgs& a) {
  if (!a.type.empty()) return true;
  const auto slash = a.pkg.find('/');
  if (slash == std::string::npos) {
    fmt::print(stderr, "tinyline run: give the node type as PKG TYPE or PKG/TYPE (tinyline nodes lists them)\n");
    return false;
  }
  a.type = a.pkg.substr(slash + 1);
  a.pkg = a.pkg.substr(0, slash);
  return true;
}

int run(RunArgs a) {
  if (!split_pkg_type(a)) return 2;
  auto ctx = bus::Context::create();
  std::shared_ptr<bus::Node> node;
  try {
    node = node_registry().create(a.pkg, a.type, node_options(a, ctx));
  } catch (const bus::ParamError& e) {
    fmt::print(stderr, "{}\n", e.what());
    return 1;
  }
  std::vector<std::shared_ptr<bus::Node>> nodes{node};
  RunOptions ro;
  if (a.dds) {
    dds::BridgeOptions bo;
    bo.settings = dds::Settings::from_environment();
    bo.settings.process_name = node->full_name();
    bo.selection.all = true;
    auto bridge = dds::Bridge::create(ctx, bo);
    bridge->announce_parameters(nodes);
    nodes.push_back(bridge);
    ro.before_spin = [bridge] { bridge->start(); };
  }
  ro.duration_s = a.duration_s;
  ro.threads = a.threads;
  ro.table = !a.no_table;
  return run_nodes(ctx, nodes, ro);
}

CommandRun setup_run(cli::App& cmd) {
  auto a = std::make_shared<RunArgs>();
  cmd.add_option("pkg", a->pkg, "package of the node type, or PKG/TYPE (tinyline nodes lists them)")->required();
  cmd.add_option("type", a->type, "the node type (or give PKG/TYPE as one word)");
  cmd.add_option("-p", a->params, "set a parameter, name:=value (YAML typing: 3, 0.5, true, [1, 2], text)")
      ->type_name("NAME:=VALUE")
      ->allow_extra_args(false);
  cmd.add_option("-r", a->remaps, "remap a topic, from:=to")->type_name("FROM:=TO")->allow_extra_args(false);
  cmd.add_option("--name", a->name, "node name (default: TYPE)");
  cmd.add_option("--ns", a->ns, "namespace")->capture_default_str();
  cmd.add_option("--duration", a->duration_s, "stop after S seconds (default: Ctrl-C)")
      ->type_name("S")
      ->check(cli::seconds());
  cmd.add_option("--threads", a->threads, "executor threads")->capture_default_str()->check(cli::threads());
  cmd.add_flag("--no-table", a->no_table, "no live topic table");
  cmd.add_flag("--dds", a->dds,
               "put the node's topics on DDS (ROS_DOMAIN_ID, CYCLONEDDS_URI; loopback by default), to join a graph "
               "started elsewhere");
  cmd.footer("Runs one node of a registered type (see `tinyline nodes`).");
  return [a] { return run(*a); };
}

const CommandRegistration kRun{"run", "run one node of a registered type", &setup_run};

}  // namespace
}  // namespace tinyline::tools
