// SPDX-License-Identifier: Apache-2.0
// Writes small valid bags of every writer variant into a directory: the seed
// corpus of bag_reader_fuzz.  Usage: bag_fuzz_seeds DIR
#include <cstdio>
#include <string>

#include <tinyline/bag/ros2.hpp>
#include <tinyline/msg/geometry_msgs/pose_stamped.hpp>
#include <tinyline/msg/std_msgs/string.hpp>

#include <tinyline/common/cli.hpp>

using namespace tinyline;
using namespace tinyline::bag;

int main(int argc, char** argv) {
  std::string dir;
  cli::App app{"Writes small valid bags of every writer variant: the seed corpus of bag_reader_fuzz.",
               "bag_fuzz_seeds"};
  app.add_option("DIR", dir, "directory to write into")->required();
  if (const auto rc = cli::parse_command_line(app, argc, argv)) return *rc;
  struct V {
    const char* name;
    WriterOptions opt;
  };
  V variants[] = {{"lz4", {}}, {"zstd", {}}, {"none", {}}, {"unchunked", {}}, {"nosummary", {}}, {"noindex", {}}};
  variants[1].opt.compression = Compression::Zstd;
  variants[2].opt.compression = Compression::None;
  variants[3].opt.chunked = false;
  variants[4].opt.summary = false;
  variants[5].opt.message_indexes = false;
  for (auto& v : variants) {
    v.opt.chunk_size_bytes = 300;
    ros2::Ros2Writer w;
    const std::string path = dir + "/seed_" + v.name + ".mcap";
    if (!w.open(path, v.opt).ok()) return 1;
    ChannelId a, b;
    if (!w.add_topic("/chatter", msg::type_support<std_msgs::msg::String>(), a).ok()) return 1;
    if (!w.add_topic("/pose", msg::type_support<geometry_msgs::msg::PoseStamped>(), b).ok()) return 1;
    for (int i = 0; i < 12; ++i) {
      std_msgs::msg::String s;
      s.data = "m" + std::to_string(i);
      geometry_msgs::msg::PoseStamped p;
      p.pose.position.x = i;
      if (!w.write(a, s, 100 + 10 * static_cast<Timestamp>(i), 100, static_cast<std::uint32_t>(i)).ok()) return 1;
      if (!w.write(b, p, 105 + 10 * static_cast<Timestamp>(12 - i), 100, static_cast<std::uint32_t>(i)).ok()) return 1;
    }
    Metadata md;
    md.name = "seed";
    md.metadata = {{"k", "v"}};
    std::vector<std::uint8_t> blob = {1, 2, 3};
    Attachment at;
    at.name = "a.bin";
    at.media_type = "application/octet-stream";
    at.data = blob;
    if (!w.writer().write(md).ok() || !w.writer().write(at).ok()) return 1;
    if (!w.close().ok()) return 1;
  }
  return 0;
}
