// tinyline: the command line of the tinyline node suite.
#include <algorithm>
#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include <fmt/format.h>

#include <tinyline/tools/command.hpp>

#include "src/args.hpp"

namespace {

void usage() {
  auto table = tinyline::tools::command_table();
  std::sort(table.begin(), table.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
  std::string s = "usage: tinyline <command> [args...]   (tinyline <command> --help for details)\n\ncommands:\n";
  for (const auto& c : table) s += fmt::format("  {:<10} {}\n", c.name, c.summary);
  std::fputs(s.c_str(), stdout);
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "--help" || args[0] == "-h" || args[0] == "help") {
    usage();
    return args.empty() ? 2 : 0;
  }
  for (const auto& c : tinyline::tools::command_table()) {
    if (c.name == args[0]) {
      try {
        return c.fn(std::vector<std::string>(args.begin() + 1, args.end()));
      } catch (const tinyline::tools::UsageError& e) {
        fmt::print(stderr, "tinyline {}: {}\n", c.name, e.what());
        return 2;
      } catch (const std::exception& e) {
        fmt::print(stderr, "tinyline {}: error: {}\n", c.name, e.what());
        return 1;
      }
    }
  }
  fmt::print(stderr, "tinyline: unknown command '{}'\n\n", args[0]);
  usage();
  return 2;
}
