// The command lines of the project's programs (evaluations, simulator tools,
// test helpers), all on CLI11: --help everywhere, and one way to fail on bad
// usage. Link tinyline::common_cli to use it.
#pragma once

#include <cmath>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

namespace tinyline::common {

/// Parses the command line. Returns the exit code when the program should
/// stop here: 0 after --help (printed on stdout), 2 after a usage error
/// (printed on stderr, with a pointer to --help); nullopt when it should run.
[[nodiscard]] inline std::optional<int> parse_command_line(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    (void)app.exit(e);
    return 2;
  }
  return std::nullopt;
}

namespace detail {
/// A validator of numbers: "" when `ok(v)` holds for the parsed value, else
/// "'TEXT' is not WHAT". NaN fails every check (CLI11's ranges let it through).
template <class Ok>
CLI::Validator number_check(const char* what, const char* name, Ok ok) {
  return CLI::Validator(
      [what, ok](std::string& s) -> std::string {
        double v = 0.0;
        if (!CLI::detail::lexical_cast(s, v) || !std::isfinite(v) || !ok(v)) return "'" + s + "' is not " + what;
        return {};
      },
      name);
}
}  // namespace detail

/// A finite number.
inline const CLI::Validator kFinite = detail::number_check("a finite number", "FINITE", [](double) { return true; });
/// A finite number > 0.
inline const CLI::Validator kPositive = detail::number_check("a finite number > 0", "POSITIVE", [](double v) { return v > 0.0; });
/// A finite number >= 0 (for unsigned options too: CLI11 would wrap "-1" around).
inline const CLI::Validator kNonNegative =
    detail::number_check("a finite number >= 0", "NON-NEGATIVE", [](double v) { return v >= 0.0; });

}  // namespace tinyline::common
