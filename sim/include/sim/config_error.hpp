// SPDX-License-Identifier: Apache-2.0
// Errors in scene and sensor configuration files. The message always names
// the file, the line and the field, e.g.
//   scenes/rail.yaml:14:7: objects[1].radius_m: must be > 0 (got -0.01)
#pragma once

#include <stdexcept>
#include <string>

namespace tinyline::sim {

class ConfigError : public std::runtime_error {
 public:
  ConfigError(std::string file, int line, int column, std::string field, const std::string& what)
      : std::runtime_error(format(file, line, column, field, what)),
        file_(std::move(file)),
        line_(line),
        column_(column),
        field_(std::move(field)) {}

  const std::string& file() const { return file_; }
  int line() const { return line_; }      ///< 1-based; 0 when unknown
  int column() const { return column_; }  ///< 1-based; 0 when unknown
  const std::string& field() const { return field_; }

 private:
  static std::string format(const std::string& file, int line, int column, const std::string& field,
                            const std::string& what) {
    std::string s = file.empty() ? std::string("<config>") : file;
    if (line > 0) s += ":" + std::to_string(line) + (column > 0 ? ":" + std::to_string(column) : "");
    s += ": ";
    if (!field.empty()) s += field + ": ";
    return s + what;
  }
  std::string file_;
  int line_ = 0;
  int column_ = 0;
  std::string field_;
};

}  // namespace tinyline::sim
