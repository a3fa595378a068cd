// A small command-line parser for the `tinyline` sub-commands.
#pragma once

#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace tinyline::tools {

class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Splits arguments into positionals, `--name value` options, `--flag`s and
/// repeated `-p x` / `-r x` style options.
class Args {
 public:
  /// `valued` lists the options that take a value (e.g. "--duration", "-p").
  Args(const std::vector<std::string>& argv, const std::vector<std::string>& valued,
       const std::vector<std::string>& flags);

  const std::vector<std::string>& positional() const { return positional_; }
  bool flag(const std::string& name) const;
  std::optional<std::string> value(const std::string& name) const;  ///< the last one given
  std::vector<std::string> values(const std::string& name) const;   ///< all, in order
  double number(const std::string& name, double fallback) const;

 private:
  std::vector<std::string> positional_;
  std::vector<std::pair<std::string, std::string>> options_;
  std::vector<std::string> flags_;
};

/// "name:=value" -> {name, value}; throws UsageError otherwise.
std::pair<std::string, std::string> split_assignment(const std::string& s);

}  // namespace tinyline::tools
