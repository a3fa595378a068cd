// SPDX-License-Identifier: Apache-2.0
// `bag recover` on files whose schema and channel records are damaged: what
// the summary still knows is recovered, and no damaged string is copied into
// the new file (whose fresh CRCs would make it look sound).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <string_view>

#include <tinyline/bag/reader.hpp>
#include <tinyline/bag/recover.hpp>
#include <tinyline/bag/ros2.hpp>
#include <tinyline/bus/names.hpp>
#include <tinyline/msg/geometry_msgs/pose_stamped.hpp>
#include <tinyline/msg/std_msgs/string.hpp>

namespace tinyline::bag {
namespace {

/// Where `text` first occurs in [begin, end), or end.
template <class T>
const T* find_text(const T* begin, const T* end, std::string_view text) {
  return std::search(begin, end, text.begin(), text.end());
}

using Bytes = std::vector<std::uint8_t>;

constexpr int kMessages = 300;

// A bag of String messages on /demo/raw and /demo/relayed in small chunks.
Bytes make_bag(bool summary = true) {
  ros2::Ros2Writer w;
  auto sink = std::make_unique<MemoryWritable>();
  auto* mem = sink.get();
  WriterOptions opt;
  opt.chunk_size_bytes = 1024;
  opt.summary = summary;
  EXPECT_TRUE(w.open(std::move(sink), opt).ok());
  ChannelId a, b;
  EXPECT_TRUE(w.add_topic("/demo/raw", msg::type_support<std_msgs::msg::String>(), a).ok());
  EXPECT_TRUE(w.add_topic("/demo/relayed", msg::type_support<std_msgs::msg::String>(), b).ok());
  for (int i = 0; i < kMessages; ++i) {
    std_msgs::msg::String m;
    m.data = "m" + std::to_string(i);
    EXPECT_TRUE(w.write(i % 2 ? a : b, m, 1000 + static_cast<Timestamp>(i), 1000, static_cast<std::uint32_t>(i)).ok());
  }
  EXPECT_TRUE(w.close().ok());
  return mem->data();
}

struct RecordAt {
  std::uint8_t op = 0;
  std::size_t offset = 0;  // of the opcode
  std::uint64_t length = 0;
};

// The records of the data section before the first chunk: header, schemas, channels.
std::vector<RecordAt> leading_records(const Bytes& f) {
  std::vector<RecordAt> out;
  std::size_t pos = 8;
  while (pos + 9 <= f.size() && f[pos] != static_cast<std::uint8_t>(Opcode::Chunk)) {
    RecordAt r{f[pos], pos, 0};
    std::memcpy(&r.length, f.data() + pos + 1, 8);
    out.push_back(r);
    pos += 9 + r.length;
  }
  return out;
}

struct Recovered {
  Status status;
  RecoverReport report;
  std::vector<std::string> topics;
  std::string profile;
  std::uint64_t messages = 0;
};

Recovered recover_bytes(const Bytes& f) {
  Recovered out;
  MemoryReadable src{std::span<const std::uint8_t>(f)};
  MemoryWritable sink;
  out.status = recover(src, sink, {}, out.report);
  if (!out.status.ok()) return out;
  Reader r;
  EXPECT_TRUE(r.open(std::make_unique<MemoryReadable>(sink.take())).ok());
  EXPECT_TRUE(r.verify().ok()) << r.verify().str();
  for (const auto& [id, ch] : r.channels()) out.topics.push_back(ch.topic);
  std::sort(out.topics.begin(), out.topics.end());
  out.profile = r.header().profile;
  out.messages = r.summary().statistics.message_count;
  return out;
}

bool mentions(const RecoverReport& rep, const std::string& text) {
  for (const auto& p : rep.problems)
    if (p.status.message.find(text) != std::string::npos) return true;
  return false;
}

TEST(Recover, ADamagedSchemaOrChannelLengthStillRecoversEveryMessageTheSummaryKnows) {
  // A length field near the start used to end the linear pass there: an
  // empty bag, exit 0, though the summary indexes every chunk.
  const Bytes good = make_bag();
  const auto recs = leading_records(good);
  ASSERT_GE(recs.size(), 4U);  // header, schema, channel, channel
  int checked = 0;
  for (const auto& r : recs) {
    if (r.op != static_cast<std::uint8_t>(Opcode::Schema) && r.op != static_cast<std::uint8_t>(Opcode::Channel))
      continue;
    for (const std::uint64_t bad :
         {std::uint64_t{0}, r.length - 1, r.length + 1, r.length + 100, std::uint64_t{1} << 40}) {
      SCOPED_TRACE(opcode_name(r.op) + " at " + std::to_string(r.offset) + " length " + std::to_string(bad));
      Bytes f = good;
      std::memcpy(f.data() + r.offset + 1, &bad, 8);
      const Recovered got = recover_bytes(f);
      ASSERT_TRUE(got.status.ok()) << got.status.str();
      EXPECT_EQ(got.messages, std::uint64_t{kMessages});
      EXPECT_EQ(got.topics, (std::vector<std::string>{"/demo/raw", "/demo/relayed"}));
      EXPECT_FALSE(got.report.problems.empty());
      ++checked;
    }
  }
  EXPECT_EQ(checked, 15);
}

TEST(Recover, ADamagedTopicInTheDataSectionIsReplacedByTheSummarysCopy) {
  // "/demo/raw" flipped to "/demo/rbw": a valid name, so only the summary's
  // copy (under its own CRC) can tell. It used to pass into the new file.
  Bytes f = make_bag();
  const auto recs = leading_records(f);
  std::size_t at = 0;
  for (const auto& r : recs) {
    if (r.op != static_cast<std::uint8_t>(Opcode::Channel)) continue;
    const auto* begin = f.data() + r.offset;
    const auto* hit = find_text(begin, begin + 9 + r.length, "/demo/raw");
    if (hit != begin + 9 + r.length) at = static_cast<std::size_t>(hit - f.data());
  }
  ASSERT_NE(at, 0U);
  f[at + 7] = 'b';
  const Recovered got = recover_bytes(f);
  ASSERT_TRUE(got.status.ok()) << got.status.str();
  EXPECT_EQ(got.topics, (std::vector<std::string>{"/demo/raw", "/demo/relayed"}));
  EXPECT_EQ(got.messages, std::uint64_t{kMessages});
  EXPECT_TRUE(mentions(got.report, "/demo/rbw")) << "the disagreement is reported";
}

// Regression: a 9-byte file (the magic and one byte) was called "empty".
TEST(Recover, AFileTooShortToHoldAHeaderIsCalledSoNotEmpty) {
  const Bytes good = make_bag();
  const Recovered got = recover_bytes(Bytes(good.begin(), good.begin() + 9));
  ASSERT_FALSE(got.status.ok());
  EXPECT_NE(got.status.message.find("9 bytes is too short for an MCAP file"), std::string::npos) << got.status.str();
  EXPECT_EQ(got.status.message.find("empty"), std::string::npos) << got.status.str();
}

TEST(Recover, WithoutASummaryStringsThatCannotBeRightAreRefusedNotCopied) {
  // No summary to compare with: a topic that is no ROS name (or no UTF-8)
  // and a profile that is no text are refused rather than written.
  const Bytes good = make_bag(false);
  const auto recs = leading_records(good);
  std::size_t topic_at = 0, profile_at = 0;
  for (const auto& r : recs) {
    const auto* begin = good.data() + r.offset;
    const auto* end = begin + 9 + r.length;
    if (r.op == static_cast<std::uint8_t>(Opcode::Channel) && topic_at == 0) {
      topic_at = static_cast<std::size_t>(find_text(begin, end, "/demo/raw") - good.data());
    }
    if (r.op == static_cast<std::uint8_t>(Opcode::Header)) {
      profile_at = static_cast<std::size_t>(find_text(begin, end, "ros2") - good.data());
    }
  }
  ASSERT_NE(topic_at, 0U);
  ASSERT_NE(profile_at, 0U);
  for (const std::uint8_t flip : {std::uint8_t{0xFF}, std::uint8_t{' '}, std::uint8_t{0x01}}) {
    SCOPED_TRACE(static_cast<int>(flip));
    Bytes f = good;
    f[topic_at + 3] = flip;
    f[profile_at + 1] = flip;
    const Recovered got = recover_bytes(f);
    ASSERT_TRUE(got.status.ok()) << got.status.str();
    EXPECT_EQ(got.profile, "ros2") << "the profile follows from the channels' cdr encoding";
    for (const auto& t : got.topics) {
      EXPECT_NO_THROW(bus::validate_name(t, "topic")) << t;
    }
    EXPECT_EQ(got.topics, std::vector<std::string>{"/demo/relayed"});
    EXPECT_EQ(got.messages, std::uint64_t{kMessages / 2});  // /demo/raw's messages have no trustworthy channel
    EXPECT_TRUE(mentions(got.report, "refused"));
  }
}

TEST(Recover, WithoutASummaryASchemaNameWithACapitalisedPackageIsRefused) {
  // One bit (0x20) turns "std_msgs" into "std_msgS": still text, still
  // UTF-8, but no ROS 2 package, and a ROS 2 reader would reject the file.
  const Bytes good = make_bag(false);
  std::size_t name_at = 0;
  for (const auto& r : leading_records(good)) {
    if (r.op != static_cast<std::uint8_t>(Opcode::Schema)) continue;
    const auto* begin = good.data() + r.offset;
    name_at = static_cast<std::size_t>(find_text(begin, begin + 9 + r.length, "std_msgs/") - good.data());
    break;
  }
  ASSERT_NE(name_at, 0U);
  Bytes f = good;
  f[name_at + 7] ^= 0x20;
  const Recovered got = recover_bytes(f);
  EXPECT_TRUE(mentions(got.report, "no ROS 2 type name")) << "the damaged schema is reported";
  if (got.status.ok()) {
    EXPECT_TRUE(got.topics.empty()) << "no channel may keep a schema that cannot be right";
  }
}

TEST(Recover, WithoutASummaryASchemaWhoseDefaultValueCannotBeRightIsRefused) {
  // One bit (0x20) turns Quaternion's "float64 w 1\n" into "float64 w 1*":
  // still text, but no number, and a ROS 2 reader refuses the whole file.
  ros2::Ros2Writer w;
  auto sink = std::make_unique<MemoryWritable>();
  auto* mem = sink.get();
  WriterOptions opt;
  opt.summary = false;
  ASSERT_TRUE(w.open(std::move(sink), opt).ok());
  ChannelId pose;
  ASSERT_TRUE(w.add_topic("/pose", msg::type_support<geometry_msgs::msg::PoseStamped>(), pose).ok());
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(w.write(pose, geometry_msgs::msg::PoseStamped{}, 1000 + i, 1000, static_cast<std::uint32_t>(i)).ok());
  }
  ASSERT_TRUE(w.close().ok());
  Bytes f = mem->data();
  const auto* at = find_text(f.data(), f.data() + f.size(), "float64 w 1\n");
  ASSERT_NE(at, f.data() + f.size()) << "Quaternion's default w is in the schema text";
  f[static_cast<std::size_t>(at - f.data()) + 11] ^= 0x20;
  const Recovered got = recover_bytes(f);
  EXPECT_TRUE(mentions(got.report, "'float64 w 1*'")) << "the damaged schema is reported";
  if (got.status.ok()) {
    EXPECT_TRUE(got.topics.empty()) << "no channel may keep a schema that cannot be right";
  }
}

}  // namespace
}  // namespace tinyline::bag
