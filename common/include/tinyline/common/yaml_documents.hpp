// SPDX-License-Identifier: Apache-2.0
// A hand-written YAML file holds one document: yaml-cpp's Load() reads the
// first and silently drops whatever follows a `---`, so readers of launch
// files and calibration files ask where a second document starts and refuse
// it. For targets that link yaml-cpp (common itself does not).
#pragma once

#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <yaml-cpp/eventhandler.h>
#include <yaml-cpp/yaml.h>

namespace tinyline::common {

namespace detail {

// Notes where each document starts; builds nothing.
class DocumentMarks : public YAML::EventHandler {
 public:
  std::vector<YAML::Mark> starts;
  void OnDocumentStart(const YAML::Mark& mark) override { starts.push_back(mark); }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark&, YAML::anchor_t) override {}
  void OnAlias(const YAML::Mark&, YAML::anchor_t) override {}
  void OnScalar(const YAML::Mark&, const std::string&, YAML::anchor_t, const std::string&) override {}
  void OnSequenceStart(const YAML::Mark&, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {}
  void OnSequenceEnd() override {}
  void OnMapStart(const YAML::Mark&, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {}
  void OnMapEnd() override {}
};

}  // namespace detail

/// Where a second YAML document of `text` starts (0-based line and column in
/// the mark), or nothing when it holds at most one. Throws
/// YAML::ParserException on a syntax error, also on a stray ',' outside any
/// [ ] or { } (not YAML::LoadAll: yaml-cpp 0.7 hands out empty documents for
/// ever after one, so only the first two are asked for).
[[nodiscard]] inline std::optional<YAML::Mark> second_document(const std::string& text) {
  std::istringstream in(text);
  YAML::Parser parser(in);
  detail::DocumentMarks marks;
  for (int i = 0; i < 3 && parser.HandleNextDocument(marks); ++i) {
    const auto n = marks.starts.size();
    if (n > 1 && marks.starts[n - 1].pos <= marks.starts[n - 2].pos) {
      throw YAML::ParserException(marks.starts.back(), "a ',' outside any [ ] or { }");
    }
  }
  if (marks.starts.size() > 1) return marks.starts[1];
  return std::nullopt;
}

}  // namespace tinyline::common
