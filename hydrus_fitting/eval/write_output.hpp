// SPDX-License-Identifier: Apache-2.0
// Where the evaluation programs put a table: stdout, or a file they name on
// stderr (so a shell pipeline keeps only the data).
#pragma once

#include <fstream>
#include <iostream>
#include <string>

namespace tinyline::hydrus_fitting::eval {

/// Writes `text` to `path` (stdout when empty); false, with the reason on
/// stderr prefixed by `program`, when the file cannot be written.
inline bool write_output(const char* program, const std::string& path, const std::string& text) {
  if (path.empty()) {
    std::cout << text;
    return true;
  }
  std::ofstream f(path);
  f << text;
  if (!f) {
    std::cerr << program << ": cannot write " << path << "\n";
    return false;
  }
  std::cerr << "wrote " << path << "\n";
  return true;
}

}  // namespace tinyline::hydrus_fitting::eval
