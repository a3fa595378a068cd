// SPDX-License-Identifier: Apache-2.0
// The command lines of every program (the `tinyline` command, evaluations,
// simulator tools, test helpers): CLI11 underneath, --help everywhere, one
// way to fail on bad usage, and one set of checks for the numbers they take.
// Every number is checked when parsed: a bad one is a usage error naming the
// option, never a silent default or a run that ignores it.
//
// This header does not include CLI11. Debian's CLI11 (2.1.2) is header-only,
// and a file that builds a CLI::App compiles the library's inline code again
// (6-8 s of CPU each at -O2 -g); through these few classes it is compiled once,
// in common/src/cli.cpp (docs/developing.md, "Build time"). The names follow
// CLI11's, so its documentation reads for them too. Link tinyline::common_cli.
//
//   tinyline::cli::App app{"What the program does.", "program"};
//   app.add_option("--trials", trials, "trials per case")->check(tinyline::cli::whole(1, 1000));
//   if (const auto rc = tinyline::cli::parse_command_line(app, argc, argv)) return *rc;
#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <iosfwd>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace CLI {
class App;
class Option;
class Validator;
}  // namespace CLI

namespace tinyline::cli {

/// A check of an option's text: returns "" when it passes, else what is
/// wrong (CLI11 prefixes the option's name). `description` shows in --help.
class Validator {
 public:
  using Check = std::function<std::string(std::string&)>;
  template <class F, std::enable_if_t<!std::is_same_v<std::decay_t<F>, Validator> &&
                                          std::is_invocable_r_v<std::string, F&, std::string&>,
                                      int> = 0>
  Validator(F check, std::string description = "")  // NOLINT(google-explicit-constructor): as CLI11's
      : Validator(Check(std::move(check)), std::move(description), 0) {}
  /// What the check says about `text`: "" when it passes.
  std::string operator()(std::string text) const;

 private:
  friend class Option;
  friend Validator range_of(double, double, bool);
  friend Validator one_of(const std::vector<std::string>&);
  friend Validator existing_file();
  Validator(Check check, std::string description, int);
  explicit Validator(std::shared_ptr<const CLI::Validator> v) : impl_(std::move(v)) {}
  std::shared_ptr<const CLI::Validator> impl_;
};

/// A number in [lo, hi], as CLI::Range (whole numbers when T is integral).
Validator range_of(double lo, double hi, bool whole);
template <class T>
Validator range(T lo, T hi) {
  return range_of(static_cast<double>(lo), static_cast<double>(hi), std::is_integral_v<T>);
}
/// One of these words, as CLI::IsMember.
Validator one_of(const std::vector<std::string>& words);
/// A file that exists, as CLI::ExistingFile.
Validator existing_file();

/// A finite number > `lo` (or >= with `inclusive`) and <= `hi`: NaN and
/// infinities are refused, as is anything out of bounds. The defaults
/// leave a side open.
Validator finite_above(double lo, bool inclusive, double hi = std::numeric_limits<double>::max());
/// Any finite number.
Validator finite();
/// A finite number > 0 (a distance, a step, a spread).
Validator positive();
/// A duration in seconds: finite and > 0.
Validator seconds();
/// A wait, offset, rate or seed that may be 0: finite and >= 0 (for unsigned
/// options too: CLI11 would wrap "-1" around).
Validator non_negative();
/// A whole number in [lo, hi].
Validator whole(long long lo, long long hi);
/// A count that may be 0 (0 often means "no limit").
Validator count();
/// Executor threads: 1..kMaxThreads.
inline constexpr int kMaxThreads = 256;
Validator threads();

/// One option or positional of an App (CLI::Option's settings the programs use).
class Option {
 public:
  Option* check(const Validator& v);
  Option* required(bool value = true);
  /// --help shows the value the variable held when the option was added.
  Option* capture_default_str();
  Option* type_name(std::string name);
  /// Splits each value at `c`: --cases a,b,c.
  Option* delimiter(char c);
  /// Exactly n values; or from min to max.
  Option* expected(int n);
  Option* expected(int min, int max);
  Option* allow_extra_args(bool value = true);

 private:
  friend class App;
  explicit Option(CLI::Option* o) : o_(o) {}
  CLI::Option* o_;
};

/// Bad usage: CLI11's own errors, and a bad value found after parsing
/// (reported as CLI11 reports one: "OPTION: MESSAGE"). App::exit prints it.
class ParseError : public std::runtime_error {
 public:
  ParseError(const std::string& option, const std::string& message);
  /// --help or --help-all was given: not an error, exit() prints the help.
  [[nodiscard]] bool help() const { return help_; }

 private:
  friend class App;
  ParseError(std::exception_ptr original, const std::string& what, bool help);
  std::exception_ptr original_;
  bool help_ = false;
};

namespace detail {
template <class T, class... Ts>
inline constexpr bool one_of_types = (std::is_same_v<T, Ts> || ...);
/// The variables an option can fill (instantiated in common/src/cli.cpp).
template <class T>
inline constexpr bool option_type =
    one_of_types<T, std::string, std::filesystem::path, double, int, unsigned, long, unsigned long,
                 std::vector<std::string>, std::vector<double>, std::vector<int>, std::optional<int>,
                 std::optional<unsigned long>, std::optional<double>, std::optional<std::string>>;
}  // namespace detail

/// A program or a sub-command (CLI::App's part the programs use).
class App {
 public:
  explicit App(std::string description = "", std::string name = "");
  ~App();
  App(const App&) = delete;
  App& operator=(const App&) = delete;

  template <class T>
  Option* add_option(std::string name, T& value, std::string description = "") {
    static_assert(detail::option_type<T>, "tinyline::cli: add this type to detail::option_type and common/src/cli.cpp");
    return add_typed_option(std::move(name), value, std::move(description));
  }
  Option* add_flag(std::string name, bool& value, std::string description = "");
  App* add_subcommand(std::string name, std::string description = "");
  void require_subcommand(int n);
  void footer(std::string text);
  /// Width of the options' column in --help (shared with sub-commands added later).
  void column_width(std::size_t width);
  /// Hands every argument after this command to the program unparsed
  /// (remaining()), --help included.
  void pass_through();
  [[nodiscard]] std::vector<std::string> remaining() const;

  /// Throws ParseError on bad usage and after --help.
  void parse(int argc, char** argv);
  /// The same for arguments already split, without the program's name
  /// (a library's command run in-process with its own streams).
  void parse(std::vector<std::string> args);
  /// Prints what `e` says (help on stdout, an error on stderr) as CLI11
  /// does; returns CLI11's exit code (0 after help).
  int exit(const ParseError& e) const;
  int exit(const ParseError& e, std::ostream& out, std::ostream& err) const;

  /// This sub-command was named on the command line.
  [[nodiscard]] bool parsed() const;
  /// The sub-commands named on the command line.
  [[nodiscard]] std::vector<const App*> parsed_subcommands() const;
  [[nodiscard]] std::string name() const;
  [[nodiscard]] std::string help() const;

 private:
  explicit App(CLI::App* sub);
  /// Runs a CLI11 parse, turning its errors into ParseError.
  static void translating_errors(const std::function<void()>& parse);
  template <class T>
  Option* add_typed_option(std::string name, T& value, std::string description);
  Option* keep(CLI::Option* o);

  std::unique_ptr<CLI::App> owned_;  ///< the root's; a sub-command's belongs to its parent's
  CLI::App* app_;
  std::vector<std::unique_ptr<Option>> options_;
  std::vector<std::unique_ptr<App>> subcommands_;
};

/// Parses the command line. Returns the exit code when the program should
/// stop here: 0 after --help (printed on stdout), 2 after a usage error
/// (printed on stderr, with a pointer to --help), 0 after a good command line
/// when only_check_options() (printed on stdout); nullopt when it should run.
[[nodiscard]] std::optional<int> parse_command_line(App& app, int argc, char** argv);
/// The same for arguments already split (no program name), printing on `out` and `err`.
[[nodiscard]] std::optional<int> parse_command_line(App& app, std::vector<std::string> args, std::ostream& out,
                                                    std::ostream& err);

/// True when the environment sets TINYLINE_CHECK_OPTIONS=1: every program
/// parses and checks its command line, says "options ok" and stops before it
/// runs. The docs test checks the long evaluations' commands this way.
[[nodiscard]] bool only_check_options();

/// What a program prints when only_check_options() stops it.
void print_options_ok(const std::string& program);

}  // namespace tinyline::cli
