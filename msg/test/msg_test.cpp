// SPDX-License-Identifier: Apache-2.0
// Messages: round trips of every type, hostile bytes, schema text, YAML, and
// interop with an independent CDR implementation (rosbags) both ways.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>

#include <tinyline/msg/all_types.hpp>

#include "fill.hpp"

using namespace tinyline;
namespace fs = std::filesystem;

namespace {

template <class T>
void round_trip_many(int seed) {
  std::mt19937_64 rng(static_cast<std::uint64_t>(seed));
  msgtest::Filler fill{rng};
  for (int i = 0; i < 100; ++i) {
    T m;
    fill.fill(m);
    const auto bytes = msg::serialize(m);
    T back;
    const auto r = msg::deserialize(bytes, back);
    ASSERT_TRUE(r.ok) << T::kTypeName << ": " << r.error;
    ASSERT_TRUE(back == m) << T::kTypeName << " did not survive a round trip";
    // The type-erased path gives the same object.
    const auto& ts = msg::type_support<T>();
    std::vector<std::uint8_t> again;
    ts.serialize(&m, again);
    ASSERT_EQ(again, bytes);
    auto erased = ts.deserialize(bytes);
    ASSERT_TRUE(*static_cast<const T*>(erased.get()) == m);
  }
}

template <class T>
void every_prefix_fails(int seed) {
  std::mt19937_64 rng(static_cast<std::uint64_t>(seed));
  msgtest::Filler fill{rng, 3};
  T m;
  fill.fill(m);
  const auto bytes = msg::serialize(m);
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    T out;
    const auto r = msg::deserialize(std::span<const std::uint8_t>(bytes.data(), n), out);
    // A strict prefix can only decode if the cut falls exactly after the last
    // field, which never happens: the writer adds no trailing padding.
    ASSERT_FALSE(r.ok) << T::kTypeName << " decoded from " << n << " of " << bytes.size() << " bytes";
    ASSERT_FALSE(r.error.empty());
  }
}

}  // namespace

TEST(Messages, EveryTypeSurvivesRandomRoundTrips) {
  int seed = 1;
#define X(pkg, T) round_trip_many<pkg::msg::T>(seed++);
  TINYLINE_FOR_EACH_MESSAGE(X)
#undef X
}

TEST(Messages, EveryTruncationOfEveryTypeIsRefusedWithoutReadingPastTheEnd) {
  int seed = 100;
#define X(pkg, T) every_prefix_fails<pkg::msg::T>(seed++);
  TINYLINE_FOR_EACH_MESSAGE(X)
#undef X
}

TEST(Messages, AHugeSequenceCountIsRefusedBeforeAllocating) {
  sensor_msgs::msg::LaserScan scan;
  scan.ranges = {1.0f, 2.0f};
  auto bytes = msg::serialize(scan);
  // ranges' count follows header (stamp 8 + frame_id "" 5 -> pad) and 7 floats.
  const std::size_t count_at = 4 + 8 + 5 + 3 + 7 * 4;
  ASSERT_EQ(bytes[count_at], 2);
  bytes[count_at] = 0xFF;
  bytes[count_at + 1] = 0xFF;
  bytes[count_at + 2] = 0xFF;
  bytes[count_at + 3] = 0x7F;
  sensor_msgs::msg::LaserScan out;
  const auto r = msg::deserialize(bytes, out);
  ASSERT_FALSE(r.ok);
  EXPECT_NE(r.error.find("field 'ranges'"), std::string::npos) << r.error;
  EXPECT_NE(r.error.find("claims 2147483647 elements"), std::string::npos) << r.error;
}

TEST(Messages, BadEncapsulationAndBadStringsAreNamed) {
  geometry_msgs::msg::Point p;
  EXPECT_NE(msg::deserialize(std::vector<std::uint8_t>{0, 1}, p).error.find("shorter than the 4-byte"),
            std::string::npos);
  EXPECT_NE(msg::deserialize(std::vector<std::uint8_t>{0, 7, 0, 0}, p).error.find("unsupported CDR encapsulation"),
            std::string::npos);
  std_msgs::msg::String s;
  s.data = "abc";
  auto bytes = msg::serialize(s);
  bytes.back() = 'x';  // the NUL terminator
  EXPECT_NE(msg::deserialize(bytes, s).error.find("not NUL-terminated"), std::string::npos);
}

TEST(Messages, BigEndianCdrDecodes) {
  // geometry_msgs/Point {1.0, -2.0, 0.5} encoded big-endian by hand.
  std::vector<std::uint8_t> be = {0x00, 0x00, 0x00, 0x00};
  for (double d : {1.0, -2.0, 0.5}) {
    std::uint8_t b[8];
    std::memcpy(b, &d, 8);
    for (int i = 7; i >= 0; --i) be.push_back(b[i]);
  }
  geometry_msgs::msg::Point p;
  ASSERT_TRUE(msg::deserialize(be, p).ok);
  EXPECT_EQ(p.x, 1.0);
  EXPECT_EQ(p.y, -2.0);
  EXPECT_EQ(p.z, 0.5);
}

TEST(Messages, SchemaTextAppendsDependenciesTheWayRosbag2Does) {
  const std::string def(msg::type_support<sensor_msgs::msg::LaserScan>().definition);
  const std::string sep = "\n" + std::string(80, '=') + "\n";
  EXPECT_EQ(def.find("# One planar scan"), 0u);
  const auto header = def.find(sep + "MSG: std_msgs/Header\n");
  const auto time = def.find(sep + "MSG: builtin_interfaces/Time\n");
  ASSERT_NE(header, std::string::npos);
  ASSERT_NE(time, std::string::npos);
  EXPECT_LT(header, time);
  EXPECT_EQ(def.find("MSG: std_msgs/Header", header + 1 + sep.size() + 5), std::string::npos);  // once each
  EXPECT_EQ(msg::type_support<sensor_msgs::msg::LaserScan>().dds_type_name(), "sensor_msgs::msg::dds_::LaserScan_");
  EXPECT_EQ(msg::find_type_support("sensor_msgs/msg/LaserScan"), &msg::type_support<sensor_msgs::msg::LaserScan>());
  EXPECT_EQ(msg::find_type_support("sensor_msgs/msg/Nope"), nullptr);
}

TEST(Messages, YamlShowsNestedFieldsListsAndElidesLongArrays) {
  sensor_msgs::msg::LaserScan scan;
  scan.header.stamp.sec = 3;
  scan.header.frame_id = "laser";
  scan.angle_min = -0.5f;
  scan.ranges = {1.0f, 2.5f, 3.0f, 4.0f};
  msg::YamlWriter y(2);
  yaml_write(y, scan);
  EXPECT_EQ(y.str(),
            "header:\n  stamp:\n    sec: 3\n    nanosec: 0\n  frame_id: \"laser\"\nangle_min: -0.5\n"
            "angle_max: 0.0\nangle_increment: 0.0\ntime_increment: 0.0\nscan_time: 0.0\nrange_min: 0.0\n"
            "range_max: 0.0\nranges: [1.0, 2.5]  # 2 more not shown\nintensities: []\n");
  visualization_msgs::msg::MarkerArray arr;
  arr.markers.resize(1);
  arr.markers[0].ns = "spheres";
  const std::string yaml = msg::to_yaml(arr);
  EXPECT_EQ(yaml.substr(0, 49), "markers:\n  - header:\n      stamp:\n        sec: 0\n");
}

TEST(Messages, InteropWithRosbagsBothWays) {
  const fs::path work = fs::temp_directory_path() / ("tinyline_cdr_interop_" + std::to_string(::getpid()));
  fs::remove_all(work);
  fs::create_directories(work);
  std::mt19937_64 rng(4242);
  msgtest::Filler fill{rng, 3};
  int written = 0;
  auto write_samples = [&]<class T>(const char* pkg, const char* name, T*) {
    for (int n = 0; n < 4; ++n) {
      T m;
      if (n > 0) fill.fill(m);  // sample 0 is the default-constructed message
      const auto bytes = msg::serialize(m);
      const std::string stem = std::string(pkg) + "__" + name + "__" + std::to_string(n);
      std::ofstream(work / (stem + ".cdr"), std::ios::binary)
          .write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
      std::ofstream(work / (stem + ".json")) << msgtest::to_json(m);
      ++written;
    }
  };
#define X(pkg, T) write_samples(#pkg, #T, static_cast<pkg::msg::T*>(nullptr));
  TINYLINE_FOR_EACH_MESSAGE(X)
#undef X
  const std::string cmd = std::string(TINYLINE_VENV_PYTHON) + " " + TINYLINE_SOURCE_DIR +
                          "/msg/test/rosbags_interop.py " + TINYLINE_SOURCE_DIR + "/msg/msg " + work.string();
  ASSERT_EQ(std::system(cmd.c_str()), 0) << "rosbags disagreed (see output above); command: " << cmd;
  // The reverse direction: decode what rosbags serialized from the same values.
  int reversed = 0;
  auto check_reverse = [&]<class T>(const char* pkg, const char* name, T*) {
    for (int n = 0; n < 4; ++n) {
      const std::string stem = std::string(pkg) + "__" + name + "__" + std::to_string(n);
      std::ifstream in(work / (stem + ".rosbags.cdr"), std::ios::binary);
      ASSERT_TRUE(in) << stem;
      std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)), {});
      std::ifstream js(work / (stem + ".json"));
      const std::string want((std::istreambuf_iterator<char>(js)), {});
      T m;
      const auto r = msg::deserialize(bytes, m);
      ASSERT_TRUE(r.ok) << stem << ": " << r.error;
      EXPECT_EQ(msgtest::to_json(m), want) << stem;
      ++reversed;
    }
  };
#define X(pkg, T) check_reverse(#pkg, #T, static_cast<pkg::msg::T*>(nullptr));
  TINYLINE_FOR_EACH_MESSAGE(X)
#undef X
  EXPECT_EQ(reversed, written);
  fs::remove_all(work);
}
