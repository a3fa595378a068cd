// tinyline launch FILE [name:=value ...] [--duration S] [--threads N] [--no-table]
#include <fmt/format.h>

#include <tinyline/launch/launch.hpp>
#include <tinyline/tools/command.hpp>

#include "../src/args.hpp"
#include "../src/graph_runner.hpp"

namespace tinyline::tools {
namespace {

constexpr const char* kHelp = R"(usage: tinyline launch FILE [name:=value ...] [options]

Runs the nodes of a launch file (ROS 2 YAML launch shape) in this process and
shows a live table of topics with rates and drops. Stops on Ctrl-C or after
--duration. Nothing starts unless the whole file is valid: errors name the
file, line and reason.

options:
  --duration S   stop after S seconds
  --threads N    executor threads (default 2)
  --no-table     no live table
  --check        validate the file and build its nodes, then exit
)";

int cmd_launch(const std::vector<std::string>& argv) {
  Args a(argv, {"--duration", "--threads"}, {"--no-table", "--check", "--help", "-h"});
  if (a.flag("--help") || a.flag("-h")) {
    fmt::print("{}", kHelp);
    return 0;
  }
  if (a.positional().empty()) throw UsageError("which launch file? (tinyline launch --help)");
  launch::LoadOptions lo;
  lo.share_dir = share_dir();
  for (std::size_t i = 1; i < a.positional().size(); ++i) lo.args.insert(split_assignment(a.positional()[i]));
  auto ctx = bus::Context::create();
  std::vector<std::shared_ptr<bus::Node>> nodes;
  try {
    const auto plan = launch::load_launch_file(a.positional()[0], lo);
    nodes = launch::instantiate(plan, node_registry(), ctx);
  } catch (const launch::LaunchError& e) {
    fmt::print(stderr, "{}\n", e.what());
    return 1;
  }
  if (a.flag("--check")) {
    fmt::print("{}: {} node(s), valid\n", a.positional()[0], nodes.size());
    return 0;
  }
  RunOptions ro;
  if (a.value("--duration")) ro.duration_s = a.number("--duration", 0);
  ro.threads = static_cast<int>(a.number("--threads", 2));
  ro.table = !a.flag("--no-table");
  return run_nodes(ctx, nodes, ro);
}

const CommandRegistration kLaunch{"launch", "run the nodes of a launch file", &cmd_launch};

}  // namespace
}  // namespace tinyline::tools
