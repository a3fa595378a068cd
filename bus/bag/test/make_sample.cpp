// SPDX-License-Identifier: Apache-2.0
// Writes the sample bag the command-line tests use (DIR/sample.mcap) and a
// copy cut mid-chunk, as a killed recorder leaves it (DIR/cut.mcap).
#include <cstdio>
#include <string>
#include <fstream>
#include <iterator>
#include <vector>

#include "sample_traffic.hpp"

#include <tinyline/common/cli.hpp>

namespace cli = tinyline::cli;

int main(int argc, char** argv) {
  using namespace tinyline::bag;
  std::string dir;
  cli::App app{
      "Writes the sample bag of the command-line tests (DIR/sample.mcap) and a copy cut mid-chunk (DIR/cut.mcap).",
      "bag_make_sample"};
  app.add_option("DIR", dir, "directory to write into")->required();
  if (const auto rc = cli::parse_command_line(app, argc, argv)) return *rc;
  ros2::Ros2Writer w;
  WriterOptions o;
  o.chunk_size_bytes = 32 * 1024;
  if (!w.open(dir + "/sample.mcap", o).ok()) return 1;
  if (!testing::write_samples(w, testing::sample_traffic(60)).ok()) return 1;
  if (!w.close().ok()) return 1;
  std::ifstream in(dir + "/sample.mcap", std::ios::binary);
  std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::ofstream cut(dir + "/cut.mcap", std::ios::binary);
  cut.write(bytes.data(), static_cast<std::streamsize>(bytes.size() / 2));
  return 0;
}
