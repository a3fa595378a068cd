#include <gtest/gtest.h>

#include <tiny_laser_driver/protocol.hpp>

namespace tl = tinyline::tiny_laser_driver;

namespace {

std::vector<std::uint8_t> make_set(std::uint16_t temp_decic, int seed) {
  std::vector<std::uint8_t> bytes;
  const std::uint16_t pulses[5] = {20, 100, 200, 400, 700};
  for (int i = 0; i < 5; ++i) {
    tl::RawFrame f;
    f.index = static_cast<std::uint16_t>(i);
    f.last = i == 4;
    f.temperature_decic = temp_decic;
    f.pulses = pulses[i];
    for (std::size_t p = 0; p < tl::kPixels; ++p) {
      f.a[p] = static_cast<std::int16_t>((seed * 31 + i * 7 + static_cast<int>(p)) % 2300);
      f.b[p] = static_cast<std::int16_t>((seed * 17 + i * 3 + static_cast<int>(p) * 2) % 2300);
    }
    tl::encode_raw_frame(f, bytes);
  }
  return bytes;
}

}  // namespace

TEST(Protocol, RawFrameLayoutMatchesWireProtocol) {
  tl::RawFrame f;
  f.index = 4;
  f.last = true;
  f.temperature_decic = 480;
  f.pulses = 700;
  f.a[0] = 0x1234;
  f.b[271] = -2;
  std::vector<std::uint8_t> out;
  tl::encode_raw_frame(f, out);
  ASSERT_EQ(out.size(), 1096u);
  EXPECT_EQ(out[0], 0xA2);
  EXPECT_EQ(out[1], 0xA1);
  EXPECT_EQ(out[2] | (out[3] << 8), 104);           // index + 100 on the last frame
  EXPECT_EQ(out[4] | (out[5] << 8), 480 * 100 + 70);  // temperature*100 + pulses/10
  EXPECT_EQ(out[6], 0x34);
  EXPECT_EQ(out[7], 0x12);
  EXPECT_EQ(out[6 + 544 + 2 * 271], 0xFE);
  EXPECT_EQ(out[6 + 544 + 2 * 271 + 1], 0xFF);
  EXPECT_EQ(out[1094], 0x2A);
  EXPECT_EQ(out[1095], 0x2B);
}

TEST(Protocol, ParsesASetFedOneByteAtATime) {
  const auto bytes = make_set(455, 1);
  tl::Parser parser;
  for (std::uint8_t b : bytes) parser.feed({&b, 1});
  auto set = parser.next_set();
  ASSERT_TRUE(set.has_value());
  ASSERT_EQ(set->frames.size(), 5u);
  EXPECT_EQ(set->frames[4].pulses, 700);
  EXPECT_EQ(set->frames[0].temperature_decic, 455);
  EXPECT_TRUE(set->frames[4].last);
  EXPECT_FALSE(parser.next_set().has_value());
  EXPECT_EQ(parser.stats().dropped(tl::DropReason::kGarbage), 0u);
}

TEST(Protocol, ResynchronisesAfterGarbageAndDropsBadEnder) {
  std::vector<std::uint8_t> bytes = {0x00, 0xA2, 0x13, 0xA1};
  auto good = make_set(400, 2);
  auto bad = make_set(400, 3);
  bad[1094] = 0x00;  // wrong ender on the first frame of this set
  bytes.insert(bytes.end(), bad.begin(), bad.end());
  bytes.insert(bytes.end(), good.begin(), good.end());
  tl::Parser parser;
  parser.feed(bytes);
  auto set = parser.next_set();
  ASSERT_TRUE(set.has_value());
  EXPECT_EQ(set->frames[0].a[5], (2 * 31 + 0 * 7 + 5) % 2300);  // the good set (seed 2)
  EXPECT_FALSE(parser.next_set().has_value());
  EXPECT_EQ(parser.stats().dropped(tl::DropReason::kBadEnder), 1u);
  EXPECT_EQ(parser.stats().dropped(tl::DropReason::kIncompleteSet), 1u);  // the bad set
  EXPECT_EQ(parser.stats().sets, 1u);
}

TEST(Protocol, HostCommandsRoundTrip) {
  tl::CommandParser cp;
  std::vector<std::uint8_t> bytes;
  for (auto& c : {tl::cmd_reset(70), tl::cmd_sample(), tl::cmd_laser(true), tl::cmd_stream_mode(tl::StreamMode::Raw)}) {
    bytes.insert(bytes.end(), c.begin(), c.end());
  }
  for (std::uint8_t b : bytes) cp.feed({&b, 1});
  auto c1 = cp.next();
  ASSERT_TRUE(c1);
  EXPECT_EQ(c1->kind, tl::HostCommand::Kind::Reset);
  EXPECT_EQ(c1->value, 700);
  EXPECT_EQ(cp.next()->kind, tl::HostCommand::Kind::Sample);
  auto c3 = cp.next();
  EXPECT_EQ(c3->kind, tl::HostCommand::Kind::Laser);
  EXPECT_EQ(c3->value, 1);
  auto c4 = cp.next();
  EXPECT_EQ(c4->kind, tl::HostCommand::Kind::StreamMode);
  EXPECT_EQ(c4->value, 1);
  EXPECT_FALSE(cp.next());
}
