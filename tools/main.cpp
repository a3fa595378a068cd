// SPDX-License-Identifier: Apache-2.0
// tinyline: the command line of the tinyline node suite.
#include <algorithm>
#include <exception>
#include <string>
#include <vector>

#include <fmt/format.h>

#include <tinyline/tools/command.hpp>

#include "src/parsing.hpp"

namespace cli = tinyline::cli;

int main(int argc, char** argv) {
  using namespace tinyline::tools;
  cli::App app("The command line of the tinyline node suite (tinyline COMMAND --help for details).", "tinyline");
  app.require_subcommand(1);
  app.column_width(24);
  auto table = command_table();
  std::sort(table.begin(), table.end(), [](const auto& a, const auto& b) { return a.name < b.name; });
  std::vector<std::pair<cli::App*, CommandRun>> runs;
  for (const auto& c : table) {
    cli::App* sub = app.add_subcommand(c.name, c.summary);
    runs.emplace_back(sub, c.setup(*sub));
  }
  const bool known = argc < 2 || argv[1][0] == '-' ||
                     std::any_of(table.begin(), table.end(), [&](const auto& c) { return c.name == argv[1]; });
  if (!known) {
    fmt::print(stderr, "tinyline: unknown command '{}'\n\n{}", argv[1], app.help());
    return 2;
  }
  std::string where = "tinyline";
  try {
    app.parse(argc, argv);
    const std::string path = parsing::command_path(app);
    where = "tinyline " + path;
    if (cli::only_check_options()) {
      cli::print_options_ok(where);
      return 0;
    }
    for (const auto& [sub, run] : runs) {
      if (sub->parsed()) return run();
    }
    return 2;
  } catch (const cli::ParseError& e) {
    if (e.help()) return app.exit(e);  // the help of the command named (0)
    const std::string path = parsing::command_path(app);
    const std::string cmd = path.empty() ? "tinyline" : "tinyline " + path;
    if (argc == 1) {
      fmt::print(stderr, "{}", app.help());
    } else {
      fmt::print(stderr, "{}: {} (see {} --help)\n", cmd, e.what(), cmd);
    }
    return 2;
  } catch (const UsageError& e) {
    fmt::print(stderr, "{}: {}\n", where, e.what());
    return 2;
  } catch (const std::exception& e) {
    fmt::print(stderr, "{}: error: {}\n", where, e.what());
    return 1;
  }
}
