// tinyline run PKG TYPE [-p name:=value] [-r from:=to] [--name N] [--ns NS] [--duration S]
#include <fmt/format.h>

#include <tinyline/dds/bridge.hpp>
#include <tinyline/tools/command.hpp>

#include "../src/args.hpp"
#include "../src/graph_runner.hpp"

namespace tinyline::tools {
namespace {

constexpr const char* kHelp = R"(usage: tinyline run PKG TYPE [options]

Runs one node of a registered type (see `tinyline nodes`).

options:
  -p name:=value   set a parameter (YAML typing: 3, 0.5, true, [1, 2], text)
  -r from:=to      remap a topic
  --name N         node name (default: TYPE)
  --ns NS          namespace (default: /)
  --duration S     stop after S seconds
  --no-table       no live topic table
  --dds            put the node's topics on DDS (ROS_DOMAIN_ID, CYCLONEDDS_URI;
                   loopback by default), to join a graph started elsewhere
)";

int cmd_run(const std::vector<std::string>& argv) {
  Args a(argv, {"-p", "-r", "--name", "--ns", "--duration", "--threads"}, {"--no-table", "--dds", "--help", "-h"});
  if (a.flag("--help") || a.flag("-h")) {
    fmt::print("{}", kHelp);
    return 0;
  }
  if (a.positional().size() != 2) throw UsageError("expected PKG TYPE (tinyline run --help)");
  auto ctx = bus::Context::create();
  bus::NodeOptions o;
  o.context = ctx;
  o.name = a.value("--name").value_or(a.positional()[1]);
  o.ns = a.value("--ns").value_or("/");
  o.where = bus::SourceLocation{"command line", 0, 0};
  for (const auto& p : a.values("-p")) {
    auto [k, v] = split_assignment(p);
    o.params.push_back({k, bus::parse_param_text(v), bus::SourceLocation{"command line (-p " + p + ")", 0, 0}});
  }
  for (const auto& r : a.values("-r")) {
    auto [from, to] = split_assignment(r);
    o.remaps.push_back({from, to});
  }
  std::shared_ptr<bus::Node> node;
  try {
    node = node_registry().create(a.positional()[0], a.positional()[1], o);
  } catch (const bus::ParamError& e) {
    fmt::print(stderr, "{}\n", e.what());
    return 1;
  }
  std::vector<std::shared_ptr<bus::Node>> nodes{node};
  RunOptions ro;
  if (a.flag("--dds")) {
    dds::BridgeOptions bo;
    bo.settings = dds::Settings::from_environment();
    bo.settings.process_name = node->full_name();
    bo.selection.all = true;
    auto bridge = dds::Bridge::create(ctx, bo);
    nodes.push_back(bridge);
    ro.before_spin = [bridge] { bridge->start(); };
  }
  if (a.value("--duration")) ro.duration_s = a.number("--duration", 0);
  ro.threads = static_cast<int>(a.number("--threads", 1));
  ro.table = !a.flag("--no-table");
  return run_nodes(ctx, nodes, ro);
}

const CommandRegistration kRun{"run", "run one node of a registered type", &cmd_run};

}  // namespace
}  // namespace tinyline::tools
