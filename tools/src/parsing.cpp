// SPDX-License-Identifier: Apache-2.0
#include "parsing.hpp"

#include <memory>

namespace tinyline::tools::parsing {

std::pair<std::string, std::string> split_assignment(const std::string& s) {
  const auto at = s.find(":=");
  if (at == std::string::npos || at == 0) throw UsageError("expected name:=value, got '" + s + "'");
  return {s.substr(0, at), s.substr(at + 2)};
}

std::map<std::string, std::string> assignments(const std::vector<std::string>& args) {
  std::map<std::string, std::string> out;
  for (const auto& a : args) out.insert(split_assignment(a));
  return out;
}

CommandRun nested(cli::App& cmd, const std::vector<Nested>& subs) {
  cmd.require_subcommand(1);
  auto runs = std::make_shared<std::vector<std::pair<cli::App*, CommandRun>>>();
  for (const auto& s : subs) {
    cli::App* sub = cmd.add_subcommand(s.name, s.summary);
    runs->emplace_back(sub, s.setup(*sub));
  }
  return [runs] {
    for (const auto& [app, run] : *runs)
      if (app->parsed()) return run();
    return 2;
  };
}

std::string command_path(const cli::App& app) {
  for (const cli::App* sub : app.parsed_subcommands()) {
    const std::string rest = command_path(*sub);
    return sub->name() + (rest.empty() ? "" : " " + rest);
  }
  return {};
}

}  // namespace tinyline::tools::parsing
