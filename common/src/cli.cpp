// SPDX-License-Identifier: Apache-2.0
// The one file that compiles CLI11 (see cli.hpp).
#include <tinyline/common/cli.hpp>

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <algorithm>
#include <string_view>

#include <CLI/CLI.hpp>

namespace tinyline::cli {

namespace {
/// The shortest text that reads back as `v` (0, 256, 0.5).
template <class T>
std::string number_text(T v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}
}  // namespace

// --- checks ---------------------------------------------------------------

Validator::Validator(Check check, std::string description, int)
    : impl_(std::make_shared<const CLI::Validator>(std::move(check), std::move(description))) {}

std::string Validator::operator()(std::string text) const { return (*impl_)(text); }

Validator range_of(double lo, double hi, bool whole) {
  if (whole) {
    return Validator(
        std::make_shared<const CLI::Validator>(CLI::Range(static_cast<long long>(lo), static_cast<long long>(hi))));
  }
  return Validator(std::make_shared<const CLI::Validator>(CLI::Range(lo, hi)));
}

Validator one_of(const std::vector<std::string>& words) {
  return Validator(std::make_shared<const CLI::Validator>(CLI::IsMember(words)));
}

Validator existing_file() { return Validator(std::make_shared<const CLI::Validator>(CLI::ExistingFile)); }

Validator finite_above(double lo, bool inclusive, double hi) {
  const bool open_below = lo == std::numeric_limits<double>::lowest();
  const bool open_above = hi == std::numeric_limits<double>::max();
  const std::string desc = !open_above  ? number_text(lo) + ".." + number_text(hi)
                           : open_below ? std::string("FINITE")
                                        : std::string("NUMBER ") + (inclusive ? ">= " : "> ") + number_text(lo);
  return Validator(
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

Validator finite() { return finite_above(std::numeric_limits<double>::lowest(), true); }
Validator positive() { return finite_above(0.0, false); }
Validator seconds() { return positive(); }
Validator non_negative() { return finite_above(0.0, true); }

Validator whole(long long lo, long long hi) {
  const bool open_above = hi == std::numeric_limits<long long>::max();
  const std::string range = number_text(lo) + ".." + number_text(hi);
  return Validator(
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

Validator count() { return whole(0, std::numeric_limits<long long>::max()); }
Validator threads() { return whole(1, kMaxThreads); }

// --- options --------------------------------------------------------------

Option* Option::check(const Validator& v) {
  o_->check(*v.impl_);
  return this;
}
Option* Option::required(bool value) {
  o_->required(value);
  return this;
}
Option* Option::capture_default_str() {
  o_->capture_default_str();
  return this;
}
Option* Option::type_name(std::string name) {
  o_->type_name(std::move(name));
  return this;
}
Option* Option::delimiter(char c) {
  o_->delimiter(c);
  return this;
}
Option* Option::expected(int n) {
  o_->expected(n);
  return this;
}
Option* Option::expected(int min, int max) {
  o_->expected(min, max);
  return this;
}
Option* Option::allow_extra_args(bool value) {
  o_->allow_extra_args(value);
  return this;
}

// --- errors ---------------------------------------------------------------

ParseError::ParseError(const std::string& option, const std::string& message)
    : ParseError(std::make_exception_ptr(CLI::ValidationError(option, message)), option + ": " + message, false) {}

ParseError::ParseError(std::exception_ptr original, const std::string& what, bool help)
    : std::runtime_error(what), original_(std::move(original)), help_(help) {}

// --- apps -----------------------------------------------------------------

App::App(std::string description, std::string name)
    : owned_(std::make_unique<CLI::App>(std::move(description), std::move(name))), app_(owned_.get()) {}

App::App(CLI::App* sub) : app_(sub) {}

App::~App() = default;

Option* App::keep(CLI::Option* o) {
  options_.push_back(std::unique_ptr<Option>(new Option(o)));
  return options_.back().get();
}

template <class T>
Option* App::add_typed_option(std::string name, T& value, std::string description) {
  return keep(app_->add_option(std::move(name), value, std::move(description)));
}

Option* App::add_flag(std::string name, bool& value, std::string description) {
  return keep(app_->add_flag(std::move(name), value, std::move(description)));
}

App* App::add_subcommand(std::string name, std::string description) {
  CLI::App* sub = app_->add_subcommand(std::move(name), std::move(description));
  subcommands_.push_back(std::unique_ptr<App>(new App(sub)));
  return subcommands_.back().get();
}

void App::require_subcommand(int n) { app_->require_subcommand(n); }
void App::footer(std::string text) { app_->footer(std::move(text)); }
void App::column_width(std::size_t width) { app_->get_formatter()->column_width(width); }

void App::pass_through() {
  app_->set_help_flag();
  app_->prefix_command();
  app_->allow_extras();
}

std::vector<std::string> App::remaining() const { return app_->remaining(); }

void App::translating_errors(const std::function<void()>& parse) {
  try {
    parse();
  } catch (const CLI::CallForHelp& e) {
    throw ParseError(std::current_exception(), e.what(), true);
  } catch (const CLI::CallForAllHelp& e) {
    throw ParseError(std::current_exception(), e.what(), true);
  } catch (const CLI::ParseError& e) {
    throw ParseError(std::current_exception(), e.what(), false);
  }
}

void App::parse(int argc, char** argv) {
  translating_errors([&] { app_->parse(argc, argv); });
}

void App::parse(std::vector<std::string> args) {
  std::reverse(args.begin(), args.end());  // CLI11 takes them last first
  translating_errors([&] { app_->parse(args); });
}

int App::exit(const ParseError& e) const { return exit(e, std::cout, std::cerr); }

int App::exit(const ParseError& e, std::ostream& out, std::ostream& err) const {
  try {
    std::rethrow_exception(e.original_);
  } catch (const CLI::Error& original) {
    return app_->exit(original, out, err);
  }
}

bool App::parsed() const { return app_->parsed(); }

std::vector<const App*> App::parsed_subcommands() const {
  std::vector<const App*> out;
  for (const CLI::App* named : app_->get_subcommands()) {
    for (const auto& sub : subcommands_) {
      if (sub->app_ == named) out.push_back(sub.get());
    }
  }
  return out;
}

std::string App::name() const { return app_->get_name(); }
std::string App::help() const { return app_->help(); }

namespace {
/// The line a program prints when only_check_options() stops it.
void options_ok(std::ostream& out, const std::string& program) { out << program << ": options ok" << std::endl; }

/// What a parse leaves the program: its exit code when it stops here.
template <class Parse>
std::optional<int> stop_or_run(App& app, Parse&& parse, std::ostream& out, std::ostream& err) {
  try {
    parse();
  } catch (const ParseError& e) {
    const int code = app.exit(e, out, err);
    return e.help() ? code : 2;
  }
  if (only_check_options()) {
    options_ok(out, app.name());
    return 0;
  }
  return std::nullopt;
}
}  // namespace

std::optional<int> parse_command_line(App& app, int argc, char** argv) {
  return stop_or_run(
      app, [&] { app.parse(argc, argv); }, std::cout, std::cerr);
}

std::optional<int> parse_command_line(App& app, std::vector<std::string> args, std::ostream& out, std::ostream& err) {
  return stop_or_run(
      app, [&] { app.parse(std::move(args)); }, out, err);
}

bool only_check_options() {
  const char* v = std::getenv("TINYLINE_CHECK_OPTIONS");
  return v != nullptr && std::string_view(v) == "1";
}

void print_options_ok(const std::string& program) { options_ok(std::cout, program); }

// The variables an option can fill (detail::option_type).
template Option* App::add_typed_option(std::string, std::string&, std::string);
template Option* App::add_typed_option(std::string, std::filesystem::path&, std::string);
template Option* App::add_typed_option(std::string, double&, std::string);
template Option* App::add_typed_option(std::string, int&, std::string);
template Option* App::add_typed_option(std::string, unsigned&, std::string);
template Option* App::add_typed_option(std::string, long&, std::string);
template Option* App::add_typed_option(std::string, unsigned long&, std::string);
template Option* App::add_typed_option(std::string, std::vector<std::string>&, std::string);
template Option* App::add_typed_option(std::string, std::vector<double>&, std::string);
template Option* App::add_typed_option(std::string, std::vector<int>&, std::string);
template Option* App::add_typed_option(std::string, std::optional<int>&, std::string);
template Option* App::add_typed_option(std::string, std::optional<unsigned long>&, std::string);
template Option* App::add_typed_option(std::string, std::optional<double>&, std::string);
template Option* App::add_typed_option(std::string, std::optional<std::string>&, std::string);

}  // namespace tinyline::cli
