// SPDX-License-Identifier: Apache-2.0
// Where the evaluation programs put a table: stdout, or a file they name on
// stderr (so a shell pipeline keeps only the data). A file is checked when
// the Output is opened, before the study runs, and replaced only by write().
#pragma once

#include <iostream>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <tinyline/common/files.hpp>

namespace tinyline::hydrus_fitting::eval {

class Output {
 public:
  /// The destination `path` (stdout when empty), never one of `inputs`, a
  /// link, a device or a FIFO; nullopt, with the reason on stderr prefixed
  /// by `program`, when it cannot be written.
  static std::optional<Output> open(const char* program, const std::string& path,
                                    std::vector<std::string> inputs = {}) {
    Output o(program);
    if (path.empty()) return o;
    try {
      o.file_.emplace(path, files::OutputOptions{.inputs = std::move(inputs), .what = "output"});
    } catch (const files::FileError& e) {
      std::cerr << program << ": " << e.what() << "\n";
      return std::nullopt;
    }
    return o;
  }

  /// Writes `text` (renamed into place); false, with the reason on stderr.
  bool write(const std::string& text) {
    if (!file_) {
      std::cout << text;
      return true;
    }
    try {
      file_->write(text);
      file_->commit();
    } catch (const files::FileError& e) {
      std::cerr << program_ << ": " << e.what() << "\n";
      return false;
    }
    std::cerr << "wrote " << file_->path() << "\n";
    return true;
  }

 private:
  explicit Output(const char* program) : program_(program) {}
  const char* program_;
  std::optional<files::AtomicFile> file_;
};

}  // namespace tinyline::hydrus_fitting::eval
