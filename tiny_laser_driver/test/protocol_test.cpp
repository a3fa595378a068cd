// SPDX-License-Identifier: Apache-2.0
// The wire protocol codec: layout, the parser under every chunking, and every
// way a serial link damages a stream (garbage, wrong enders, lost frames,
// frames of the other mode, impossible fields), each drop counted by reason.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <random>

#include <tiny_laser_driver/protocol.hpp>

namespace tl = tinyline::tiny_laser_driver;
using Bytes = std::vector<std::uint8_t>;

namespace {

constexpr std::uint16_t kPulses[5] = {20, 100, 200, 400, 700};

tl::RawFrame make_frame(int i, std::uint16_t temp_decic, int seed, int n = 5) {
  tl::RawFrame f;
  f.index = static_cast<std::uint16_t>(i);
  f.last = i == n - 1;
  f.temperature_decic = temp_decic;
  f.pulses = kPulses[i % 5] + static_cast<std::uint16_t>(i / 5 * 700);
  for (std::size_t p = 0; p < tl::kPixels; ++p) {
    f.a[p] = static_cast<std::int16_t>((seed * 31 + i * 7 + static_cast<int>(p)) % 2300);
    f.b[p] = static_cast<std::int16_t>((seed * 17 + i * 3 + static_cast<int>(p) * 2) % 2300);
  }
  return f;
}

Bytes make_set(std::uint16_t temp_decic, int seed) {
  Bytes bytes;
  for (int i = 0; i < 5; ++i) tl::encode_raw_frame(make_frame(i, temp_decic, seed), bytes);
  return bytes;
}

Bytes make_distance(int seed) {
  tl::DistanceFrame d;
  for (std::size_t p = 0; p < tl::kPixels; ++p) d.distance[p] = static_cast<std::uint16_t>((seed * 13 + p * 5) % 2000);
  Bytes out;
  tl::encode_distance_frame(d, out);
  return out;
}

void append(Bytes& a, const Bytes& b) { a.insert(a.end(), b.begin(), b.end()); }

std::vector<tl::RawSet> drain(tl::Parser& p) {
  std::vector<tl::RawSet> out;
  while (auto s = p.next_set()) out.push_back(std::move(*s));
  return out;
}

bool same_frame(const tl::RawFrame& x, const tl::RawFrame& y) {
  return x.index == y.index && x.last == y.last && x.temperature_decic == y.temperature_decic && x.pulses == y.pulses &&
         x.a == y.a && x.b == y.b && x.end_byte == y.end_byte;
}

bool same_sets(const std::vector<tl::RawSet>& x, const std::vector<tl::RawSet>& y) {
  if (x.size() != y.size()) return false;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (x[i].frames.size() != y[i].frames.size()) return false;
    for (std::size_t j = 0; j < x[i].frames.size(); ++j) {
      if (!same_frame(x[i].frames[j], y[i].frames[j])) return false;
    }
  }
  return true;
}

bool same_stats(const tl::ParserStats& a, const tl::ParserStats& b) {
  return a.drops == b.drops && a.frames == b.frames && a.frames_discarded == b.frames_discarded && a.sets == b.sets &&
         a.bytes == b.bytes && a.impossible_values == b.impossible_values;
}

std::uint64_t d(const tl::Parser& p, tl::DropReason r) { return p.stats().dropped(r); }

}  // namespace

// ------------------------------------------------------------------ layout

TEST(Protocol, RawFrameLayoutMatchesWireProtocol) {
  tl::RawFrame f;
  f.index = 4;
  f.last = true;
  f.temperature_decic = 480;
  f.pulses = 700;
  f.a[0] = 0x1234;
  f.b[271] = -2;
  Bytes out;
  tl::encode_raw_frame(f, out);
  ASSERT_EQ(out.size(), 1096u);
  EXPECT_EQ(out[0], 0xA2);
  EXPECT_EQ(out[1], 0xA1);
  EXPECT_EQ(out[2] | (out[3] << 8), 104);             // index + 100 on the last frame
  EXPECT_EQ(out[4] | (out[5] << 8), 480 * 100 + 70);  // temperature*100 + pulses/10
  EXPECT_EQ(out[6], 0x34);
  EXPECT_EQ(out[7], 0x12);
  EXPECT_EQ(out[6 + 544 + 2 * 271], 0xFE);
  EXPECT_EQ(out[6 + 544 + 2 * 271 + 1], 0xFF);
  EXPECT_EQ(out[1094], 0x2A);
  EXPECT_EQ(out[1095], 0x2B);
}

TEST(Protocol, DistanceFrameLayoutMatchesWireProtocol) {
  tl::DistanceFrame f;
  f.distance[0] = 0x0102;
  f.distance[271] = 1500;
  Bytes out;
  tl::encode_distance_frame(f, out);
  ASSERT_EQ(out.size(), 548u);
  EXPECT_EQ(out[0], 0xA2);
  EXPECT_EQ(out[1], 0xA1);
  EXPECT_EQ(out[2], 0x02);
  EXPECT_EQ(out[3], 0x01);
  EXPECT_EQ(out[2 + 2 * 271] | (out[3 + 2 * 271] << 8), 1500);
  EXPECT_EQ(out[546], 0x2A);
  EXPECT_EQ(out[547], 0x2B);
}

TEST(Protocol, EncoderRefusesFieldsThePackedWordCannotCarry) {
  Bytes out;
  tl::RawFrame f;
  f.pulses = 705;
  EXPECT_THROW(tl::encode_raw_frame(f, out), std::invalid_argument);
  f.pulses = 1000;
  EXPECT_THROW(tl::encode_raw_frame(f, out), std::invalid_argument);
  f.pulses = 700;
  f.temperature_decic = 655;  // 65570 does not fit 16 bits
  EXPECT_THROW(tl::encode_raw_frame(f, out), std::invalid_argument);
  f.pulses = 350;  // 65535 does
  EXPECT_NO_THROW(tl::encode_raw_frame(f, out));
  EXPECT_EQ(out.size(), tl::kRawFrameBytes);
}

// ------------------------------------------------------------------ chunking

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
  EXPECT_EQ(set->end_byte(), bytes.size());
  EXPECT_EQ(set->frames[0].end_byte, tl::kRawFrameBytes);
  EXPECT_FALSE(parser.next_set().has_value());
  EXPECT_EQ(parser.stats().bytes, bytes.size());
  EXPECT_EQ(d(parser, tl::DropReason::kGarbage), 0u);
  EXPECT_EQ(parser.buffered(), 0u);
}

TEST(Protocol, EverySplitOfARawSetGivesTheSameSet) {
  const auto bytes = make_set(470, 3);
  tl::Parser whole;
  whole.feed(bytes);
  const auto expected = drain(whole);
  ASSERT_EQ(expected.size(), 1u);
  for (std::size_t k = 0; k <= bytes.size(); ++k) {
    tl::Parser p;
    p.feed({bytes.data(), k});
    p.feed({bytes.data() + k, bytes.size() - k});
    const auto got = drain(p);
    ASSERT_TRUE(same_sets(got, expected)) << "split at byte " << k;
    ASSERT_TRUE(same_stats(p.stats(), whole.stats())) << "split at byte " << k;
  }
}

TEST(Protocol, EveryTwoWaySplitOfAFrameGivesTheSameFrame) {
  // A one-frame set, so every (i, j) pair of cut points of one raw frame is covered.
  Bytes bytes;
  tl::encode_raw_frame(make_frame(0, 400, 5, 1), bytes);
  const tl::Parser::Options one{1};
  tl::Parser whole(one);
  whole.feed(bytes);
  const auto expected = drain(whole);
  ASSERT_EQ(expected.size(), 1u);
  const std::size_t n = bytes.size();
  for (std::size_t i = 0; i <= n; ++i) {
    for (std::size_t j = i; j <= n; ++j) {
      tl::Parser p(one);
      p.feed({bytes.data(), i});
      p.feed({bytes.data() + i, j - i});
      p.feed({bytes.data() + j, n - j});
      auto got = p.next_set();
      ASSERT_TRUE(got.has_value()) << "cuts at " << i << ", " << j;
      ASSERT_TRUE(same_frame(got->frames[0], expected[0].frames[0])) << "cuts at " << i << ", " << j;
      ASSERT_EQ(p.stats().bytes, n);
      ASSERT_EQ(p.stats().frames, 1u);
    }
  }
}

TEST(Protocol, EveryTwoWaySplitOfADistanceFrameGivesTheSameFrame) {
  const auto bytes = make_distance(7);
  const tl::Parser::Options opt{5};
  tl::Parser whole(opt);
  whole.feed(bytes);
  const auto expected = whole.next_distance();
  ASSERT_TRUE(expected.has_value());
  EXPECT_EQ(expected->end_byte, bytes.size());
  const std::size_t n = bytes.size();
  for (std::size_t i = 0; i <= n; ++i) {
    for (std::size_t j = i; j <= n; ++j) {
      tl::Parser p(opt);
      p.feed({bytes.data(), i});
      p.feed({bytes.data() + i, j - i});
      p.feed({bytes.data() + j, n - j});
      auto got = p.next_distance();
      ASSERT_TRUE(got.has_value()) << "cuts at " << i << ", " << j;
      ASSERT_EQ(got->distance, expected->distance);
      ASSERT_FALSE(p.next_distance().has_value());
    }
  }
}

// ------------------------------------------------------------------ resynchronisation and drops

TEST(Protocol, ResynchronisesAfterGarbageAndDropsBadEnder) {
  Bytes bytes = {0x00, 0xA2, 0x13, 0xA1};
  auto good = make_set(400, 2);
  auto bad = make_set(400, 3);
  bad[1094] = 0x00;  // wrong ender on the first frame of this set
  append(bytes, bad);
  append(bytes, good);
  tl::Parser parser;
  parser.feed(bytes);
  auto set = parser.next_set();
  ASSERT_TRUE(set.has_value());
  EXPECT_EQ(set->frames[0].a[5], (2 * 31 + 0 * 7 + 5) % 2300);  // the good set (seed 2)
  EXPECT_FALSE(parser.next_set().has_value());
  EXPECT_EQ(d(parser, tl::DropReason::kBadEnder), 1u);
  EXPECT_EQ(d(parser, tl::DropReason::kIncompleteSet), 1u);  // the bad set, counted once
  EXPECT_EQ(parser.stats().frames_discarded, 4u);            // its other four frames
  // 4 leading bytes + the bad frame's body after its header (the hunt skips it).
  EXPECT_EQ(d(parser, tl::DropReason::kGarbage), 4u + tl::kRawFrameBytes - 2);
  EXPECT_EQ(parser.stats().sets, 1u);
}

TEST(Protocol, GarbageBetweenSetsIsCountedByteForByte) {
  std::mt19937 rng(11);
  Bytes stream;
  std::uint64_t garbage = 0;
  for (int s = 0; s < 20; ++s) {
    const std::size_t n = rng() % 300;
    for (std::size_t i = 0; i < n; ++i) {
      std::uint8_t b = static_cast<std::uint8_t>(rng());
      if (b == 0xA2) b = 0x55;  // no header byte: every garbage byte is counted as such
      stream.push_back(b);
    }
    garbage += n;
    append(stream, make_set(450, s));
  }
  tl::Parser p;
  p.feed(stream);
  EXPECT_EQ(drain(p).size(), 20u);
  EXPECT_EQ(d(p, tl::DropReason::kGarbage), garbage);
  EXPECT_EQ(p.stats().frames_dropped(), 0u);
  EXPECT_EQ(d(p, tl::DropReason::kIncompleteSet), 0u);
}

TEST(Protocol, FalseHeadersInGarbageCostNothingButTheirOwnCount) {
  // Garbage full of header patterns: each false header costs a bad-ender drop,
  // and no real set is lost, because the hunt resumes right after it.
  Bytes stream;
  for (int k = 0; k < 50; ++k) {
    stream.push_back(0xA2);
    stream.push_back(0xA1);
    stream.push_back(0x00);
  }
  append(stream, make_set(450, 1));
  for (int k = 0; k < 3; ++k) append(stream, {0xA2, 0xA1});
  append(stream, make_set(450, 2));
  tl::Parser p;
  p.feed(stream);
  EXPECT_EQ(drain(p).size(), 2u);
  EXPECT_EQ(d(p, tl::DropReason::kIncompleteSet), 0u);
  EXPECT_GE(d(p, tl::DropReason::kBadEnder), 50u);
}

TEST(Protocol, ASetMissingAnyMemberIsDroppedAndCountedOnce) {
  for (int missing = 0; missing < 5; ++missing) {
    Bytes stream = make_set(450, 1);
    Bytes broken;
    for (int i = 0; i < 5; ++i) {
      if (i != missing) tl::encode_raw_frame(make_frame(i, 450, 2), broken);
    }
    append(stream, broken);
    append(stream, make_set(450, 3));
    tl::Parser p;
    p.feed(stream);
    const auto sets = drain(p);
    ASSERT_EQ(sets.size(), 2u) << "missing frame " << missing;
    EXPECT_EQ(sets[0].frames[0].a[0], make_frame(0, 450, 1).a[0]);
    EXPECT_EQ(sets[1].frames[0].a[0], make_frame(0, 450, 3).a[0]);
    EXPECT_EQ(d(p, tl::DropReason::kIncompleteSet), 1u) << "missing frame " << missing;
    EXPECT_EQ(sets[0].sequence, 0u);
    EXPECT_EQ(sets[1].sequence, 2u);  // the gap is the broken set
    EXPECT_EQ(p.stats().frames_discarded, 4u) << "missing frame " << missing;
    EXPECT_EQ(p.stats().frames, 14u);
  }
}

TEST(Protocol, TwoNeighbouringBrokenSetsCountTwice) {
  // The tail of one set and the head of the next are lost together: the index
  // going back from 3 to 1 still shows two sets.
  Bytes stream;
  for (int i = 0; i < 4; ++i) tl::encode_raw_frame(make_frame(i, 450, 1), stream);
  for (int i = 1; i < 5; ++i) tl::encode_raw_frame(make_frame(i, 450, 2), stream);
  append(stream, make_set(450, 3));
  tl::Parser p;
  p.feed(stream);
  EXPECT_EQ(drain(p).size(), 1u);
  EXPECT_EQ(d(p, tl::DropReason::kIncompleteSet), 2u);
  EXPECT_EQ(p.stats().frames_discarded, 8u);
}

TEST(Protocol, EverySingleBitFlipInTheFramingCostsOneSetCountedOnce) {
  // Three sets; one bit of a framing byte (header, index word, packed word,
  // ender) of one frame of the middle set flips. The books must balance:
  // published + incomplete = 3, whatever the flip. (A corrupted index used to
  // look like the start of a new set, counting one damaged set twice.)
  const Bytes clean = [] {
    Bytes b;
    for (int s = 0; s < 3; ++s) append(b, make_set(450, s));
    return b;
  }();
  int published_middle = 0;
  for (std::size_t frame = 0; frame < 5; ++frame) {
    for (std::size_t off : {0u, 1u, 2u, 3u, 4u, 5u, 1094u, 1095u}) {
      for (int bit = 0; bit < 8; ++bit) {
        Bytes b = clean;
        b[5 * tl::kRawFrameBytes + frame * tl::kRawFrameBytes + off] ^= static_cast<std::uint8_t>(1u << bit);
        tl::Parser p;
        p.feed(b);
        const auto sets = drain(p);
        const std::string where =
            "frame " + std::to_string(frame) + " byte " + std::to_string(off) + " bit " + std::to_string(bit);
        EXPECT_EQ(sets.size() + d(p, tl::DropReason::kIncompleteSet), 3u) << where;
        ASSERT_GE(sets.size(), 2u) << where;  // the neighbours are never touched
        EXPECT_EQ(sets.front().frames[0].a[0], make_frame(0, 450, 0).a[0]) << where;
        EXPECT_EQ(sets.back().frames[0].a[0], make_frame(0, 450, 2).a[0]) << where;
        if (sets.size() == 3) {
          // Only a packed-word flip that keeps the pulses rising can pass.
          EXPECT_TRUE(off == 4 || off == 5) << where;
          ++published_middle;
        }
      }
    }
  }
  EXPECT_LT(published_middle, 5 * 16);  // most packed-word flips break the pulse order
}

TEST(Protocol, FramesWithImpossibleFieldsAreDropped) {
  Bytes stream;
  auto zero_pulses = make_frame(2, 450, 1);
  zero_pulses.pulses = 0;
  for (int i = 0; i < 5; ++i) tl::encode_raw_frame(i == 2 ? zero_pulses : make_frame(i, 450, 1), stream);
  auto big_index = make_frame(3, 450, 2);
  big_index.index = 7;  // beyond a 5-frame set
  for (int i = 0; i < 5; ++i) tl::encode_raw_frame(i == 3 ? big_index : make_frame(i, 450, 2), stream);
  append(stream, make_set(450, 3));
  tl::Parser p;
  p.feed(stream);
  EXPECT_EQ(drain(p).size(), 1u);
  EXPECT_EQ(d(p, tl::DropReason::kBadField), 2u);
  EXPECT_EQ(d(p, tl::DropReason::kIncompleteSet), 2u);
}

TEST(Protocol, PulsesThatDoNotRiseBreakTheSet) {
  Bytes stream;
  for (int i = 0; i < 5; ++i) {
    auto f = make_frame(i, 450, 1);
    if (i == 3) f.pulses = 100;  // a corrupted packed word: below frame 2's 200
    tl::encode_raw_frame(f, stream);
  }
  append(stream, make_set(450, 2));
  tl::Parser p;
  p.feed(stream);
  EXPECT_EQ(drain(p).size(), 1u);
  EXPECT_EQ(d(p, tl::DropReason::kIncompleteSet), 1u);
}

TEST(Protocol, ASetFlaggedTooEarlyOrNotAtAllIsIncomplete) {
  Bytes stream;
  for (int i = 0; i < 3; ++i) {
    auto f = make_frame(i, 450, 1);
    f.last = i == 2;  // flagged after three of five
    tl::encode_raw_frame(f, stream);
  }
  for (int i = 0; i < 5; ++i) {
    auto f = make_frame(i, 450, 2);
    f.last = false;  // never flagged
    tl::encode_raw_frame(f, stream);
  }
  append(stream, make_set(450, 3));
  tl::Parser p;
  p.feed(stream);
  const auto sets = drain(p);
  ASSERT_EQ(sets.size(), 1u);
  EXPECT_EQ(sets[0].frames[0].a[0], make_frame(0, 450, 3).a[0]);
  EXPECT_EQ(d(p, tl::DropReason::kIncompleteSet), 2u);
}

TEST(Protocol, ReadsBothKindsOfFrameWithoutBeingTold) {
  // Distance frames (the published firmware) and raw sets (the thesis's) in
  // one stream, told apart by where their ender is.
  Bytes stream = make_distance(1);
  append(stream, make_distance(2));
  append(stream, make_set(450, 1));
  append(stream, make_distance(3));
  tl::Parser p;
  p.feed(stream);
  EXPECT_EQ(drain(p).size(), 1u);
  int frames = 0;
  while (p.next_distance()) ++frames;
  EXPECT_EQ(frames, 3);
  EXPECT_EQ(p.stats().distance_frames, 3u);
  EXPECT_EQ(p.stats().raw_frames, 5u);
  EXPECT_EQ(p.stats().frames_dropped(), 0u);
  EXPECT_EQ(d(p, tl::DropReason::kGarbage), 0u);
}

TEST(Protocol, DistancesAreUnsignedUpTo65535) {
  // The published firmware stores (uint16)(cm * 100): 3.28-6.55 m are
  // values above 32767, ranges, not negative numbers.
  tl::DistanceFrame f;
  f.distance[8] = 32768;
  f.distance[9] = 60000;
  f.distance[10] = 65535;
  Bytes bytes;
  tl::encode_distance_frame(f, bytes);
  EXPECT_EQ(bytes[2 + 2 * 9], 0x60);  // 60000 = 0xEA60, little-endian
  EXPECT_EQ(bytes[2 + 2 * 9 + 1], 0xEA);
  tl::Parser p;
  p.feed(bytes);
  const auto got = p.next_distance();
  ASSERT_TRUE(got);
  EXPECT_EQ(got->distance[8], 32768);
  EXPECT_EQ(got->distance[9], 60000);
  EXPECT_EQ(got->distance[10], 65535);
}

TEST(Protocol, TheLastFrameIsAboveOneHundredAsThePublicDriverReadsIt) {
  EXPECT_EQ(tl::last_frame_word(4, true), 104);
  EXPECT_EQ(tl::last_frame_word(3, false), 3);
  EXPECT_EQ(tl::last_frame_word(0, true), 101);  // a set of one: 100 would not be "last" (num > 100)
  Bytes one;
  tl::encode_raw_frame(make_frame(0, 250, 1, 1), one);
  EXPECT_EQ(one[2] | (one[3] << 8), 101);
  tl::Parser single({1});
  single.feed(one);
  const auto set = single.next_set();
  ASSERT_TRUE(set);
  EXPECT_EQ(set->frames[0].index, 0);
  EXPECT_TRUE(set->frames[0].last);
  // Index word 100 is no frame of any set.
  one[2] = 100;
  one[3] = 0;
  tl::Parser p({1});
  p.feed(one);
  EXPECT_FALSE(p.next_set());
  EXPECT_EQ(d(p, tl::DropReason::kBadField), 1u);
}

TEST(Protocol, ResetCountsTheFrameAndSetItCuts) {
  const auto bytes = make_set(450, 1);
  tl::Parser p;
  p.feed({bytes.data(), 2 * tl::kRawFrameBytes + 100});  // two frames and a bit
  EXPECT_EQ(p.pending_frames(), 2u);
  EXPECT_EQ(p.buffered(), 100u);
  p.reset();
  EXPECT_EQ(d(p, tl::DropReason::kTruncated), 1u);
  EXPECT_EQ(d(p, tl::DropReason::kIncompleteSet), 1u);
  EXPECT_EQ(p.buffered(), 0u);
  // The rest of the cut set arrives after the reconnect: it cannot make a set.
  p.feed({bytes.data() + 2 * tl::kRawFrameBytes + 100, bytes.size() - 2 * tl::kRawFrameBytes - 100});
  const auto next = make_set(450, 2);
  p.feed(next);
  const auto sets = drain(p);
  ASSERT_EQ(sets.size(), 1u);
  EXPECT_EQ(sets[0].frames[0].a[0], make_frame(0, 450, 2).a[0]);
  EXPECT_EQ(d(p, tl::DropReason::kIncompleteSet), 2u);  // the cut set, and its tail seen after the reset
}

TEST(Protocol, ImpossiblePixelValuesAreCountedNotHidden) {
  auto f0 = make_frame(0, 450, 1);
  f0.a[10] = 5000;
  f0.b[11] = -4096;
  Bytes stream;
  tl::encode_raw_frame(f0, stream);
  for (int i = 1; i < 5; ++i) tl::encode_raw_frame(make_frame(i, 450, 1), stream);
  tl::Parser p;
  p.feed(stream);
  EXPECT_EQ(drain(p).size(), 1u);
  EXPECT_EQ(p.stats().impossible_values, 2u);
}

TEST(Protocol, SetTemperatureIsTheMedianOfItsFrames) {
  tl::RawSet s;
  for (std::uint16_t t : {450, 451, 9999, 450, 452}) {
    tl::RawFrame f;
    f.temperature_decic = t;
    s.frames.push_back(f);
  }
  EXPECT_EQ(s.temperature_decic(), 451);
  EXPECT_EQ(tl::RawSet{}.temperature_decic(), 0);
}

TEST(Protocol, RejectsImpossibleOptions) {
  EXPECT_THROW(tl::Parser({0}), std::invalid_argument);
  EXPECT_THROW(tl::Parser({100}), std::invalid_argument);
}

// ------------------------------------------------------------------ properties over damaged streams

namespace {

struct Damaged {
  Bytes bytes;
  int sets = 0;
};

// Sets with random damage: flipped bytes, dropped bytes, inserted bytes, garbage runs.
Damaged damaged_stream(std::uint32_t seed, int sets, double byte_error) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  Damaged out;
  out.sets = sets;
  for (int s = 0; s < sets; ++s) {
    Bytes set = make_set(static_cast<std::uint16_t>(440 + s % 20), s);
    for (std::uint8_t b : set) {
      const double x = u(rng);
      if (x < byte_error / 3) continue;                                  // dropped
      if (x < 2 * byte_error / 3) b = static_cast<std::uint8_t>(rng());  // flipped
      out.bytes.push_back(b);
      if (x > 1.0 - byte_error / 3) out.bytes.push_back(static_cast<std::uint8_t>(rng()));  // inserted
    }
  }
  return out;
}

}  // namespace

TEST(Protocol, DamagedStreamsParseTheSameInAnyChunking) {
  for (std::uint32_t seed = 1; seed <= 20; ++seed) {
    const auto stream = damaged_stream(seed, 20, seed % 2 ? 1e-3 : 1e-4);
    tl::Parser whole;
    whole.feed(stream.bytes);
    const auto expected = drain(whole);
    std::mt19937 rng(seed * 7);
    tl::Parser chunked;
    std::size_t at = 0;
    while (at < stream.bytes.size()) {
      const std::size_t n = std::min<std::size_t>(stream.bytes.size() - at, rng() % 3000);
      chunked.feed({stream.bytes.data() + at, n});
      at += n;
    }
    EXPECT_TRUE(same_sets(drain(chunked), expected)) << "seed " << seed;
    EXPECT_TRUE(same_stats(chunked.stats(), whole.stats())) << "seed " << seed;
  }
}

TEST(Protocol, EveryByteIsAccountedFor) {
  // bytes fed = accepted frames + dropped frames (their consumed bytes) +
  // garbage + bytes still buffered: nothing vanishes uncounted.
  for (std::uint32_t seed = 1; seed <= 20; ++seed) {
    const auto stream = damaged_stream(seed, 30, 2e-3);
    tl::Parser p;
    p.feed(stream.bytes);
    drain(p);
    const auto& s = p.stats();
    const std::uint64_t accounted = (s.raw_frames + s.dropped(tl::DropReason::kBadField)) * tl::kRawFrameBytes +
                                    s.distance_frames * tl::kDistanceFrameBytes +
                                    s.dropped(tl::DropReason::kBadEnder) * 2 + s.dropped(tl::DropReason::kGarbage) +
                                    p.buffered();
    EXPECT_EQ(accounted, s.bytes) << "seed " << seed;
    // Every well-formed frame ends up in a set or is counted as discarded.
    EXPECT_EQ(s.raw_frames, s.sets * 5 + s.frames_discarded + p.pending_frames()) << "seed " << seed;
  }
}

TEST(Protocol, OnlyWholeUndamagedSetsComeOut) {
  // With byte flips only (no slips), a set comes out only if every one of its
  // frames kept its header, index, packed word and ender.
  std::mt19937 rng(5);
  Bytes stream;
  std::vector<Bytes> originals;
  for (int s = 0; s < 200; ++s) originals.push_back(make_set(450, s));
  std::size_t intact_sets = 0;
  for (const auto& set : originals) {
    Bytes b = set;
    bool framing_hit = false;
    for (std::size_t i = 0; i < b.size(); ++i) {
      if (rng() % 2000 == 0) {
        b[i] ^= static_cast<std::uint8_t>(1 + rng() % 255);
        const std::size_t off = i % tl::kRawFrameBytes;
        if (off < 6 || off >= tl::kRawFrameBytes - 2) framing_hit = true;
      }
    }
    intact_sets += framing_hit ? 0 : 1;
    append(stream, b);
  }
  tl::Parser p;
  p.feed(stream);
  const auto sets = drain(p);
  for (const auto& s : sets) {
    ASSERT_EQ(s.frames.size(), 5u);
    for (std::size_t i = 0; i < 5; ++i) {
      EXPECT_EQ(s.frames[i].index, i);
      EXPECT_EQ(s.frames[i].pulses, kPulses[i]);
    }
    EXPECT_TRUE(s.frames[4].last);
  }
  // A flip in a pixel byte cannot be seen (no checksum); one in a framing byte
  // always is, except flips that keep the fields plausible (rare): allow those.
  EXPECT_LE(sets.size(), originals.size());
  EXPECT_GE(sets.size(), intact_sets);
  EXPECT_LE(sets.size() - intact_sets, 2u);
}

// ------------------------------------------------------------------ host commands

TEST(Protocol, HostCommandsRoundTrip) {
  tl::CommandParser cp;
  Bytes bytes;
  for (auto& c : {tl::cmd_reset(70), tl::cmd_sample(), tl::cmd_laser(true), tl::cmd_stream_mode(tl::StreamMode::Raw),
                  tl::cmd_framed_reset(-300), tl::cmd_sample_restart(), tl::cmd_laser(false)}) {
    append(bytes, c);
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
  auto c5 = cp.next();
  EXPECT_EQ(c5->kind, tl::HostCommand::Kind::FramedReset);
  EXPECT_EQ(c5->value, -300);
  EXPECT_EQ(cp.next()->kind, tl::HostCommand::Kind::SampleRestart);
  auto c7 = cp.next();
  EXPECT_EQ(c7->kind, tl::HostCommand::Kind::Laser);
  EXPECT_EQ(c7->value, 0);
  EXPECT_FALSE(cp.next());
  EXPECT_EQ(cp.garbage(), 0u);
}

TEST(Protocol, LaserCommandBytesAreTheDocumentedOnes) {
  EXPECT_EQ(tl::cmd_laser(true), (Bytes{0xF8, 0x02, 0x10, 0x01, 0x8F}));
  EXPECT_EQ(tl::cmd_laser(false), (Bytes{0xF8, 0x02, 0x10, 0x00, 0x8F}));
  EXPECT_EQ(tl::cmd_stream_mode(tl::StreamMode::Distance), (Bytes{0xF8, 0x02, 0x11, 0x00, 0x8F}));
  EXPECT_EQ(tl::cmd_framed_reset(700), (Bytes{0xF8, 0x03, 0x01, 0xBC, 0x02, 0x8F}));
}

TEST(Protocol, CommandParserSkipsBrokenFramedCommands) {
  tl::CommandParser cp;
  Bytes bytes = {0xF8, 0x02, 0x10, 0x01, 0x00};  // wrong end byte
  append(bytes, tl::cmd_laser(true));
  cp.feed(bytes);
  auto c = cp.next();
  ASSERT_TRUE(c);
  EXPECT_EQ(c->kind, tl::HostCommand::Kind::Laser);
  EXPECT_FALSE(cp.next());
  EXPECT_GT(cp.garbage(), 0u);
}
