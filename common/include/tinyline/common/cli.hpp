// The command lines of every program (the `tinyline` command, evaluations,
// simulator tools, test helpers), all on CLI11: --help everywhere, one way to
// fail on bad usage, and one set of checks for the numbers they take. Every
// number is checked when parsed: a bad one is a usage error naming the
// option, never a silent default or a run that ignores it. Link
// tinyline::common_cli to use it.
#pragma once

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <limits>
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
/// The shortest text that reads back as `v` (0, 256, 0.5).
template <class T>
std::string number_text(T v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}
}  // namespace detail

/// A finite number > `lo` (or >= with `inclusive`) and <= `hi`: NaN and
/// infinities are refused, as is anything out of bounds. The defaults
/// leave a side open.
inline CLI::Validator finite_above(double lo, bool inclusive, double hi = std::numeric_limits<double>::max()) {
  using detail::number_text;
  const bool open_below = lo == std::numeric_limits<double>::lowest();
  const bool open_above = hi == std::numeric_limits<double>::max();
  const std::string desc = !open_above  ? number_text(lo) + ".." + number_text(hi)
                           : open_below ? std::string("FINITE")
                                        : std::string("NUMBER ") + (inclusive ? ">= " : "> ") + number_text(lo);
  return CLI::Validator(
      [lo, inclusive, hi](std::string& text) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        if (text.empty() || end == nullptr || *end != '\0') return "'" + text + "' is not a number";
        if (!std::isfinite(v)) return "'" + text + "' is not a finite number";
        if (inclusive ? v < lo : v <= lo) {
          return text + " must be " + (inclusive ? "at least " : "greater than ") + number_text(lo);
        }
        if (v > hi) return text + " must be at most " + number_text(hi);
        return {};
      },
      desc);
}
/// Any finite number.
inline CLI::Validator finite() { return finite_above(std::numeric_limits<double>::lowest(), true); }
/// A finite number > 0 (a distance, a step, a spread).
inline CLI::Validator positive() { return finite_above(0.0, false); }
/// A duration in seconds: finite and > 0.
inline CLI::Validator seconds() { return positive(); }
/// A wait, offset, rate or seed that may be 0: finite and >= 0 (for unsigned
/// options too: CLI11 would wrap "-1" around).
inline CLI::Validator non_negative() { return finite_above(0.0, true); }

/// A whole number in [lo, hi].
inline CLI::Validator whole(long long lo, long long hi) {
  using detail::number_text;
  const bool open_above = hi == std::numeric_limits<long long>::max();
  const std::string range = number_text(lo) + ".." + number_text(hi);
  return CLI::Validator(
      [lo, hi, open_above, range](std::string& text) -> std::string {
        char* end = nullptr;
        errno = 0;
        const long long v = std::strtoll(text.c_str(), &end, 10);
        if (text.empty() || *end != '\0') return "'" + text + "' is not a whole number";
        if (errno == ERANGE || v < lo || v > hi) {
          return open_above ? text + " must be at least " + number_text(lo) : text + " is outside " + range;
        }
        return {};
      },
      open_above ? "N >= " + number_text(lo) : range);
}
/// A count that may be 0 (0 often means "no limit").
inline CLI::Validator count() { return whole(0, std::numeric_limits<long long>::max()); }
/// Executor threads: 1..kMaxThreads.
inline constexpr int kMaxThreads = 256;
inline CLI::Validator threads() { return whole(1, kMaxThreads); }

}  // namespace tinyline::common
