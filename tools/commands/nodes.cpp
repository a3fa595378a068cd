// SPDX-License-Identifier: Apache-2.0
// tinyline nodes | tinyline describe PKG/TYPE
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

#include <tinyline/tools/command.hpp>

#include "../src/parsing.hpp"

namespace tinyline::tools {
namespace {

CommandRun setup_nodes(cli::App& cmd) {
  cmd.footer("Lists every registered node type (what a launch file's pkg/exec can name).");
  return [] {
    for (const auto* t : node_registry().all()) fmt::print("{:<40} {}\n", t->full_name(), t->description);
    return 0;
  };
}

// A node of type `full` (PKG/TYPE) built with its defaults, on a sim clock
// that logs nowhere; nullptr (with the reason on stderr) if it cannot be.
// A required parameter (a file to read at start) has no default: it is
// given an empty text here, only to see the declarations; constructors
// read no files (they open them in on_start()).
// An empty regular file that lives as long as the program (removed at exit).
// mkstemp makes a new name exclusively: never a file someone put there.
std::string placeholder_file() {
  static const std::string path = [] {
    std::string p = (std::filesystem::temp_directory_path() / "tinyline_describe_XXXXXX").string();
    const int fd = ::mkstemp(p.data());
    if (fd < 0) throw std::runtime_error("cannot create a placeholder file in " + p + ": " + std::strerror(errno));
    ::close(fd);
    return p;
  }();
  static const bool removed_at_exit = [] { return std::atexit([] { ::unlink(path.c_str()); }) == 0; }();
  (void)removed_at_exit;
  return path;
}

std::shared_ptr<bus::Node> build_default(const std::string& full) {
  const auto slash = full.find('/');
  if (slash == std::string::npos) throw UsageError("expected PKG/TYPE, got '" + full + "'");
  bus::ContextOptions co;
  co.clock = bus::ClockType::Sim;
  co.log_sink = std::make_shared<bus::CaptureSink>();
  bus::NodeOptions o;
  o.context = bus::Context::create(co);
  o.name = full.substr(slash + 1);
  // The bus says "parameter 'NAME' is required" or "parameter 'NAME' (what) is required".
  constexpr std::string_view kParameter = "parameter '";
  for (int tries = 0;; ++tries) {
    try {
      return node_registry().create(full.substr(0, slash), full.substr(slash + 1), o);
    } catch (const bus::ParamError& e) {
      const std::string what = e.what();
      const auto required = what.find(" is required");
      const auto start = required == std::string::npos ? required : what.rfind(kParameter, required);
      const auto end = start == std::string::npos ? start : what.find('\'', start + kParameter.size());
      if (end == std::string::npos || end > required || tries >= 16) {
        fmt::print(stderr, "{}\n", what);
        return nullptr;
      }
      // An empty text first; a node that refuses it (a file it checks when
      // built) gets an empty regular file.
      const std::string name = what.substr(start + kParameter.size(), end - start - kParameter.size());
      const bool again = std::any_of(o.params.begin(), o.params.end(), [&](const auto& p) { return p.name == name; });
      o.param(name, again ? placeholder_file() : std::string());
    }
  }
}

std::string range_of(const bus::ParamConstraints& c) {
  std::string range;
  if (c.min) range += fmt::format(" min {}", *c.min);
  if (c.max) range += fmt::format(" max {}", *c.max);
  if (!c.choices.empty()) {
    range += " one of";
    for (const auto& w : c.choices) range += " " + w;
  }
  return range.empty() ? range : range.substr(1);
}

std::string default_of(const bus::ParamDescriptor& p) {
  return p.constraints.required ? "required" : "default " + bus::format_value(p.default_value);
}

void print_text(const std::string& full, const bus::Node& n) {
  const auto slash = full.find('/');
  const auto* info = node_registry().find(full.substr(0, slash), full.substr(slash + 1));
  fmt::print("{}: {}\n\nparameters:\n", full, info->description);
  for (const auto& p : n.parameters()) {
    const std::string range = range_of(p.constraints);
    const std::string unit = p.constraints.unit.empty() ? "" : " [" + p.constraints.unit + "]";
    fmt::print("  {:<24} {:<13} {}{}\n      {}{}\n", p.name, bus::to_string(p.type), default_of(p),
               range.empty() ? "" : " (" + range + ")", p.description, unit);
  }
  const auto d = n.describe();
  fmt::print("\npublishes:\n");
  for (const auto& e : d.publishers) fmt::print("  {:<30} {:<36} {}\n", e.topic, e.type, e.qos.describe());
  fmt::print("\nsubscribes:\n");
  for (const auto& e : d.subscriptions) fmt::print("  {:<30} {:<36} {}\n", e.topic, e.type, e.qos.describe());
}

// The parameters as the docs' table (docs/parameters.md is this, for every type).
void print_markdown(const std::string& full, const bus::Node& n) {
  const auto slash = full.find('/');
  const auto* info = node_registry().find(full.substr(0, slash), full.substr(slash + 1));
  fmt::print("## `{}`\n\n{}\n\n", full, info->description);
  if (n.parameters().empty()) {
    fmt::print("No parameters.\n\n");
    return;
  }
  fmt::print("| parameter | type | default | range | unit | description |\n|---|---|---|---|---|---|\n");
  for (const auto& p : n.parameters()) {
    std::string what = p.description;
    for (std::size_t at = 0; (at = what.find('|', at)) != std::string::npos; at += 2) what.replace(at, 1, "\\|");
    fmt::print("| `{}` | {} | {} | {} | {} | {} |\n", p.name, bus::to_string(p.type),
               p.constraints.required ? "required" : "`" + bus::format_value(p.default_value) + "`",
               range_of(p.constraints), p.constraints.unit, what);
  }
  fmt::print("\n");
}

int describe(const std::string& full, bool markdown) {
  const auto n = build_default(full);
  if (!n) return 1;
  markdown ? print_markdown(full, *n) : print_text(full, *n);
  return 0;
}

// Every registered type as markdown: the text of docs/parameters.md.
int describe_all() {
  fmt::print(
      "# Node parameters\n\n"
      "Every node type's parameters: name, type, default, range, unit and what it means. This file is made\n"
      "by `tinyline describe --all --markdown > docs/parameters.md` from the settings' tables the nodes\n"
      "declare their parameters from; the test `params.docs_match_the_tables` fails when it is out of date.\n\n");
  int rc = 0;
  for (const auto* t : node_registry().all()) rc = std::max(rc, describe(t->full_name(), true));
  return rc;
}

CommandRun setup_describe(cli::App& cmd) {
  struct Args {
    std::string type;
    bool markdown = false;
    bool all = false;
  };
  auto a = std::make_shared<Args>();
  cmd.add_option("type", a->type, "the node type, PKG/TYPE (tinyline nodes lists them)");
  cmd.add_flag("--markdown", a->markdown, "print the parameters as a markdown table (the docs' form)");
  cmd.add_flag("--all", a->all, "every registered node type (with --markdown: docs/parameters.md)");
  cmd.footer(
      "Shows a node type's parameters (type, default, range, unit, description) and its topics with types "
      "and QoS.");
  return [a] {
    if (a->all == !a->type.empty()) throw UsageError("give either a node type (PKG/TYPE) or --all");
    if (a->all && !a->markdown) throw UsageError("--all needs --markdown");
    return a->all ? describe_all() : describe(a->type, a->markdown);
  };
}

const CommandRegistration kNodes{"nodes", "list registered node types", &setup_nodes};
const CommandRegistration kDescribe{"describe", "show a node type's parameters and topics", &setup_describe};

}  // namespace
}  // namespace tinyline::tools
