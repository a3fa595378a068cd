// Writes the sample bag the command-line tests use (DIR/sample.mcap) and a
// copy cut mid-chunk, as a killed recorder leaves it (DIR/cut.mcap).
#include <cstdio>
#include <fstream>
#include <iterator>
#include <vector>

#include "sample_traffic.hpp"

int main(int argc, char** argv) {
  using namespace tinyline::bag;
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s DIR\n", argv[0]);
    return 2;
  }
  const std::string dir = argv[1];
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
