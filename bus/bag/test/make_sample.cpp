// SPDX-License-Identifier: Apache-2.0
// Writes the sample bag the command-line tests use (DIR/sample.mcap) and a
// copy cut mid-chunk, as a killed recorder leaves it (DIR/cut.mcap).
#include <cstdio>
#include <string>
#include <string_view>

#include "sample_traffic.hpp"

#include <tinyline/common/cli.hpp>
#include <tinyline/common/files.hpp>

namespace cli = tinyline::cli;

int main(int argc, char** argv) {
  using namespace tinyline::bag;
  std::string dir;
  cli::App app{
      "Writes the sample bag of the command-line tests (DIR/sample.mcap) and a copy cut mid-chunk (DIR/cut.mcap).",
      "bag_make_sample"};
  app.add_option("DIR", dir, "directory to write into")->required();
  if (const auto rc = cli::parse_command_line(app, argc, argv)) return *rc;
  for (const char* name : {"/sample.mcap", "/cut.mcap"})
    if (!tinyline::files::output_allowed("bag_make_sample", dir + name, tinyline::files::named("bag"))) return 1;
  ros2::Ros2Writer w;
  WriterOptions o;
  o.chunk_size_bytes = 32 * 1024;
  Status s = w.open(dir + "/sample.mcap", o);
  if (s.ok()) s = testing::write_samples(w, testing::sample_traffic(60));
  if (s.ok()) s = w.close();
  if (!s.ok()) {
    std::fprintf(stderr, "bag_make_sample: %s\n", s.str().c_str());
    return 1;
  }
  try {
    const std::string bytes = tinyline::files::read_text(dir + "/sample.mcap", "bag", 0);
    tinyline::files::write_atomically(dir + "/cut.mcap", std::string_view(bytes).substr(0, bytes.size() / 2),
                                      tinyline::files::named("bag"));
  } catch (const tinyline::files::FileError& e) {
    std::fprintf(stderr, "bag_make_sample: %s\n", e.what());
    return 1;
  }
  return 0;
}
