// SPDX-License-Identifier: Apache-2.0
// Writes seed inputs for driver_parser_fuzz into the directory given: raw
// sets and distance frames, clean and with the damage a serial link does.
// Input layout: byte 0 = (readouts - 1) << 1 (bit 0 unused), byte 1 = chunking seed.
#include <cstdio>
#include <string>
#include <vector>

#include <tiny_laser_driver/protocol.hpp>

#include <tinyline/common/cli.hpp>
#include <tinyline/common/files.hpp>

namespace cli = tinyline::cli;

namespace tl = tinyline::tiny_laser_driver;

namespace {

std::vector<std::uint8_t> raw_set(int seed) {
  std::vector<std::uint8_t> out;
  const std::uint16_t pulses[5] = {20, 100, 200, 400, 700};
  for (int i = 0; i < 5; ++i) {
    tl::RawFrame f;
    f.index = static_cast<std::uint16_t>(i);
    f.last = i == 4;
    f.temperature_decic = 450;
    f.pulses = pulses[i];
    for (std::size_t p = 0; p < tl::kPixels; ++p) {
      f.a[p] = static_cast<std::int16_t>((seed * 31 + i * 7 + static_cast<int>(p)) % 2300);
      f.b[p] = static_cast<std::int16_t>((seed * 17 + i * 3 + static_cast<int>(p) * 2) % 2300);
    }
    tl::encode_raw_frame(f, out);
  }
  return out;
}

std::vector<std::uint8_t> distance_frame(int seed) {
  tl::DistanceFrame d;
  for (std::size_t p = 0; p < tl::kPixels; ++p) d.distance[p] = static_cast<std::uint16_t>((seed + p) % 2000);
  std::vector<std::uint8_t> out;
  tl::encode_distance_frame(d, out);
  return out;
}

void write(const std::string& dir, const std::string& name, std::uint8_t mode, const std::vector<std::uint8_t>& body) {
  std::string bytes{static_cast<char>(mode), 7};
  bytes.append(reinterpret_cast<const char*>(body.data()), body.size());
  tinyline::files::write_atomically(dir + "/" + name, bytes, tinyline::files::named("seed"));
}

}  // namespace

void write_seeds(const std::string& dir);

int main(int argc, char** argv) {
  std::string dir;
  cli::App app{"Writes the seed corpus of the driver's parser fuzzer.", "driver_parser_fuzz_seeds"};
  app.add_option("SEED_DIR", dir, "directory to write into")->required();
  if (const auto rc = cli::parse_command_line(app, argc, argv)) return *rc;
  try {
    write_seeds(dir);
  } catch (const tinyline::files::FileError& e) {
    std::fprintf(stderr, "driver_parser_fuzz_seeds: %s\n", e.what());
    return 1;
  }
  return 0;
}

void write_seeds(const std::string& dir) {
  const std::uint8_t raw5 = 4 << 1;  // readouts 5, raw mode
  auto two = raw_set(1);
  const auto second = raw_set(2);
  two.insert(two.end(), second.begin(), second.end());
  write(dir, "raw_two_sets", raw5, two);
  auto bad_ender = two;
  bad_ender[1094] = 0;
  write(dir, "raw_bad_ender", raw5, bad_ender);
  auto missing = two;
  missing.erase(missing.begin() + 2 * 1096, missing.begin() + 3 * 1096);
  write(dir, "raw_missing_member", raw5, missing);
  auto slipped = two;
  slipped.erase(slipped.begin() + 3000);
  write(dir, "raw_dropped_byte", raw5, slipped);
  std::vector<std::uint8_t> mixed = distance_frame(1);
  mixed.insert(mixed.end(), two.begin(), two.end());
  write(dir, "raw_after_distance", raw5, mixed);
  std::vector<std::uint8_t> dist = distance_frame(1);
  const auto d2 = distance_frame(2);
  dist.insert(dist.end(), d2.begin(), d2.end());
  write(dir, "distance_two", 1, dist);
  write(dir, "distance_then_raw", 1, mixed);
}
