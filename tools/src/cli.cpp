#include "cli.hpp"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <memory>

#include <fmt/format.h>

namespace tinyline::tools::cli {

CLI::Validator finite_above(double lo, bool inclusive, double hi) {
  const bool bounded = hi < std::numeric_limits<double>::max();
  const std::string desc = bounded ? fmt::format("{}..{}", lo, hi) : fmt::format("NUMBER {} {}", inclusive ? ">=" : ">", lo);
  return CLI::Validator(
      [lo, inclusive, hi](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (text.empty() || end == nullptr || *end != '\0') return fmt::format("'{}' is not a number", text);
        if (!std::isfinite(v)) return fmt::format("'{}' is not a finite number", text);
        if (inclusive ? v < lo : v <= lo) {
          return fmt::format("{} must be {} {}", text, inclusive ? "at least" : "greater than", lo);
        }
        if (v > hi) return fmt::format("{} must be at most {}", text, hi);
        return {};
      },
      desc);
}

CLI::Validator whole(long long lo, long long hi) {
  const std::string desc = hi == std::numeric_limits<long long>::max() ? fmt::format("N >= {}", lo)
                                                                         : fmt::format("{}..{}", lo, hi);
  return CLI::Validator(
      [lo, hi](std::string& text) -> std::string {
        char* end = nullptr;
        errno = 0;
        const long long v = std::strtoll(text.c_str(), &end, 10);
        if (text.empty() || *end != '\0') return fmt::format("'{}' is not a whole number", text);
        if (errno == ERANGE || v < lo || v > hi) {
          return hi == std::numeric_limits<long long>::max() ? fmt::format("{} must be at least {}", text, lo)
                                                             : fmt::format("{} is outside {}..{}", text, lo, hi);
        }
        return {};
      },
      desc);
}

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

CommandRun nested(CLI::App& cmd, const std::vector<Nested>& subs) {
  cmd.require_subcommand(1);
  auto runs = std::make_shared<std::vector<std::pair<CLI::App*, CommandRun>>>();
  for (const auto& s : subs) {
    CLI::App* sub = cmd.add_subcommand(s.name, s.summary);
    runs->emplace_back(sub, s.setup(*sub));
  }
  return [runs] {
    for (const auto& [app, run] : *runs)
      if (app->parsed()) return run();
    return 2;
  };
}

std::string command_path(const CLI::App& app) {
  for (const CLI::App* sub : app.get_subcommands()) {
    const std::string rest = command_path(*sub);
    return sub->get_name() + (rest.empty() ? "" : " " + rest);
  }
  return {};
}

}  // namespace tinyline::tools::cli
