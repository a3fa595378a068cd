// SPDX-License-Identifier: Apache-2.0
// Repeats, torn frames, stale pixels, the unit check and the command watch,
// on hand-made streams.
#include <gtest/gtest.h>

#include <tiny_laser_driver/stream_health.hpp>

namespace tl = tinyline::tiny_laser_driver;

namespace {

tl::DistanceFrame frame(std::uint16_t base) {
  tl::DistanceFrame f;
  for (std::size_t p = 8; p < 264; ++p) f.distance[p] = static_cast<std::uint16_t>(base + 3 * p);
  return f;
}

constexpr std::int64_t kFrameNs = 2'740'000;

}  // namespace

TEST(StreamHealth, ARepeatingStreamGivesEachContentOnceAtItsFirstArrival) {
  tl::DistanceRepeats r(25'000'000);
  std::vector<tl::DistanceRepeats::Fresh> out;
  std::int64_t t = 0;
  auto push = [&](const tl::DistanceFrame& f) {
    if (auto x = r.push(f, t)) out.push_back(*x);
    t += kFrameNs;
  };
  for (int i = 0; i < 5; ++i) push(frame(1000));
  const std::int64_t second_first = t;
  for (int i = 0; i < 5; ++i) push(frame(2000));
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out[0].stamp_ns, 0);
  EXPECT_EQ(out[1].stamp_ns, second_first);
  EXPECT_EQ(r.stats().repeats, 8u);
  EXPECT_EQ(r.stats().fresh, 2u);
  EXPECT_TRUE(r.repeating());
}

TEST(StreamHealth, ATornFrameIsNeverAMeasurement) {
  tl::DistanceRepeats r(25'000'000);
  std::vector<tl::DistanceRepeats::Fresh> out;
  std::int64_t t = 0;
  auto push = [&](const tl::DistanceFrame& f) {
    if (auto x = r.push(f, t)) out.push_back(*x);
    t += kFrameNs;
  };
  for (int i = 0; i < 3; ++i) push(frame(1000));
  for (std::size_t cut : {9u, 130u, 263u}) {  // a tear at a word, inside the line, near its end
    const auto old_content = out.back().frame;
    const auto next = frame(static_cast<std::uint16_t>(1000 + 100 * cut));
    tl::DistanceFrame torn = old_content;
    std::copy(next.distance.begin() + static_cast<std::ptrdiff_t>(cut), next.distance.end(),
              torn.distance.begin() + static_cast<std::ptrdiff_t>(cut));
    push(torn);
    const std::int64_t first = t;
    for (int i = 0; i < 3; ++i) push(next);
    ASSERT_EQ(out.back().frame.distance, next.distance) << cut;
    EXPECT_EQ(out.back().stamp_ns, first) << cut;
  }
  EXPECT_EQ(out.size(), 4u);
  EXPECT_EQ(r.stats().torn, 3u);
}

TEST(StreamHealth, AStreamThatDoesNotRepeatIsPassedOnAtOnce) {
  tl::DistanceRepeats r(25'000'000);
  for (int i = 0; i < 10; ++i) {
    const auto x = r.push(frame(static_cast<std::uint16_t>(100 * i)), i * 28'000'000LL);
    ASSERT_TRUE(x.has_value()) << i;
    EXPECT_EQ(x->stamp_ns, i * 28'000'000LL);
  }
  EXPECT_FALSE(r.repeating());
  EXPECT_EQ(r.stats().repeats, 0u);
}

TEST(StreamHealth, AHeldContentIsPublishedWhenTheStreamStops) {
  tl::DistanceRepeats r(25'000'000);
  EXPECT_TRUE(r.push(frame(1), 0));
  EXPECT_FALSE(r.push(frame(1), kFrameNs));      // repeating now
  EXPECT_FALSE(r.push(frame(2), 2 * kFrameNs));  // held: torn or not?
  EXPECT_FALSE(r.flush(2 * kFrameNs + 10'000'000));
  const auto x = r.flush(2 * kFrameNs + 25'000'000);
  ASSERT_TRUE(x);
  EXPECT_EQ(x->stamp_ns, 2 * kFrameNs);
}

TEST(StreamHealth, AStuckPixelAndItsStuckNeighboursAreFlagged) {
  tl::StalePixels s(5);
  std::array<std::uint32_t, tl::kPixels> v{};
  for (int k = 0; k < 8; ++k) {
    for (std::size_t p = 8; p < 264; ++p) v[p] = static_cast<std::uint32_t>(1000 + p + 7 * k);
    v[100] = 4000;                    // one stuck pixel
    v[200] = v[201] = v[202] = 5000;  // a stuck patch
    s.update(v);
    if (k < 5) {
      EXPECT_EQ(s.count(), 0) << k;
    }
  }
  EXPECT_TRUE(s.flags()[100]);
  EXPECT_TRUE(s.flags()[200] && s.flags()[201] && s.flags()[202]);
  EXPECT_FALSE(s.flags()[99] || s.flags()[101] || s.flags()[0]);
  EXPECT_EQ(s.count(), 4);
  // A scene where nothing moves (no noise) flags nothing: no neighbour changed.
  tl::StalePixels still(5);
  for (std::size_t p = 8; p < 264; ++p) v[p] = 1000;
  for (int k = 0; k < 10; ++k) still.update(v);
  EXPECT_EQ(still.count(), 0);
}

TEST(StreamHealth, AWrongUnitShowsInTheShareOfValidPixels) {
  tl::ProcessedScan scan;
  scan.status.fill(tl::PixelStatus::kValid);
  scan.distance_m.fill(5.0f);  // millimetres read as 0.1 mm would be 10x too near; as metres 10x too far
  tl::RangeShares far;
  far.add(scan);
  EXPECT_NE(far.verdict().find("beyond 2 m"), std::string::npos) << far.verdict();
  scan.distance_m.fill(0.03f);
  tl::RangeShares near;
  near.add(scan);
  EXPECT_NE(near.verdict().find("under 0.05 m"), std::string::npos) << near.verdict();
  scan.distance_m.fill(0.7f);
  tl::RangeShares fine;
  fine.add(scan);
  EXPECT_EQ(fine.verdict(), "");
}

TEST(StreamHealth, CommandsAreJudgedByWhatTheStreamDoesAfterThem) {
  const std::int64_t grace = 75'000'000;
  tl::CommandWatch obeyed(grace), ignored(grace);
  const std::uint16_t schedule[5] = {20, 100, 200, 400, 700};
  for (tl::CommandWatch* w : {&obeyed, &ignored}) {
    w->laser_sent(false, 0);
    w->measured(tl::StreamMode::Raw, schedule, 30'000'000);  // in flight: within the grace
  }
  ignored.measured(tl::StreamMode::Distance, {}, 150'000'000);  // the published firmware goes on
  for (tl::CommandWatch* w : {&obeyed, &ignored}) w->laser_sent(true, 300'000'000);
  EXPECT_EQ(obeyed.laser_off().obeyed, 1u);
  EXPECT_FALSE(obeyed.ignores_laser_off());
  EXPECT_EQ(ignored.laser_off().ignored, 1u);
  EXPECT_TRUE(ignored.ignores_laser_off());

  tl::CommandWatch mode(grace);
  mode.stream_mode_sent(tl::StreamMode::Raw, 0);
  mode.measured(tl::StreamMode::Distance, {}, 200'000'000);
  EXPECT_EQ(mode.stream_mode().ignored, 1u);
  mode.reset_sent(250, 300'000'000);
  mode.measured(tl::StreamMode::Raw, schedule, 500'000'000);  // the pulse count did not change
  EXPECT_EQ(mode.reset().ignored, 1u);
  const std::uint16_t shot[1] = {250};
  mode.reset_sent(250, 600'000'000);
  mode.measured(tl::StreamMode::Raw, shot, 800'000'000);
  EXPECT_EQ(mode.reset().obeyed, 1u);
  EXPECT_NE(mode.summary().find("reset: sent 2, obeyed 1, ignored 1"), std::string::npos) << mode.summary();
}
