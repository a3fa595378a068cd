// SPDX-License-Identifier: Apache-2.0
#include <gtest/gtest.h>

#include <cmath>

#include "tomato_reasoning/hsi_filter.hpp"

using namespace tinyline::tomato_reasoning;

namespace {
// The reference: PCL's PackedHSIComparison arithmetic with atan2, hue in degrees.
bool reference_passes(const Rgb& c, const HsiFilterParams& p) {
  const int r = c[0], g = c[1], b = c[2];
  const double hx = (2.0 * r - g - b) / 4.0, hy = (g - b) * 111.0 / 255.0;
  const double h = std::atan2(hy, hx) * 180.0 / M_PI;
  const int i = (r + g + b) / 3;
  const int m = std::min({r, g, b});
  const int s = i == 0 ? 0 : 255 - (m * 255) / i;
  return h >= p.h_min_deg && h <= p.h_max_deg && s >= p.s_min && s <= p.s_max && i >= p.i_min && i <= p.i_max;
}
double hue(const Rgb& c) { return to_hsi(c).h_deg; }
}  // namespace

TEST(HsiFilter, MatchesPclArithmeticOnEveryThirdColour) {
  for (const HsiFilterParams& p :
       {HsiFilterParams{}, HsiFilterParams{-170, 170, 0, 255, 0, 255}, HsiFilterParams{60, 150, 30, 200, 20, 220},
        HsiFilterParams{-180, 180, 100, 250, 25, 180}}) {
    const HsiFilter f(p);
    long mismatches = 0, passing = 0;
    for (int r = 0; r < 256; r += 3)
      for (int g = 0; g < 256; g += 3)
        for (int b = 0; b < 256; b += 3) {
          const Rgb c{std::uint8_t(r), std::uint8_t(g), std::uint8_t(b)};
          const bool ref = reference_passes(c, p);
          passing += ref;
          // A colour exactly on a hue bound may round either way.
          if (f.passes(c) != ref && std::abs(hue(c) - p.h_min_deg) > 1e-9 && std::abs(hue(c) - p.h_max_deg) > 1e-9)
            ++mismatches;
        }
    EXPECT_EQ(mismatches, 0) << "range [" << p.h_min_deg << ", " << p.h_max_deg << "]";
    EXPECT_GT(passing, 0);
  }
}

TEST(HsiFilter, ThesisRangesKeepRipeRedAndDropFoliageAndHighlights) {
  const HsiFilter f;                        // -15..15 deg, S 100..250, I 25..180
  EXPECT_TRUE(f.passes({200, 40, 30}));     // ripe tomato, lit
  EXPECT_TRUE(f.passes({110, 30, 25}));     // ripe tomato in shade
  EXPECT_FALSE(f.passes({60, 130, 40}));    // leaf
  EXPECT_FALSE(f.passes({250, 200, 190}));  // specular highlight: too bright, too pale
  EXPECT_FALSE(f.passes({20, 5, 4}));       // too dark (I < 25)
  EXPECT_FALSE(f.passes({200, 120, 30}));   // orange: hue beyond 15 deg
  EXPECT_FALSE(f.passes({128, 128, 128}));  // grey: no saturation
  const Hsi x = to_hsi({255, 0, 0});
  EXPECT_NEAR(x.h_deg, 0.0, 1e-12);
  EXPECT_EQ(x.s, 255);
  EXPECT_EQ(x.i, 85);
}

TEST(HsiFilter, KeepsOnlyFinitePointsThatPass) {
  ColorCloud c;
  c.push_back({0, 0, 0.5}, {200, 40, 30});
  c.push_back({NAN, 0, 0.5}, {200, 40, 30});  // red but no depth
  c.push_back({0, 0, 0.5}, {60, 130, 40});
  c.push_back({0.1f, 0, 0.5}, {190, 35, 30});
  const HsiFilterResult r = filter_hsi(c);
  EXPECT_EQ(r.indices, (Indices{0, 3}));
  EXPECT_EQ(r.finite, 3u);
  EXPECT_TRUE(r.status.ok());
}

TEST(HsiFilter, BadInputGivesAnEmptyResultWithTheReason) {
  ColorCloud empty;
  EXPECT_EQ(filter_hsi(empty).status.message, "empty cloud");
  EXPECT_EQ(filter_hsi(empty).status.code, tinyline::common::StatusCode::NotFound);
  ColorCloud nan;
  for (int k = 0; k < 5; ++k) nan.push_back({NAN, NAN, NAN}, {200, 40, 30});
  EXPECT_NE(filter_hsi(nan).status.message.find("no point of the cloud has depth"), std::string::npos);
  ColorCloud green;
  for (int k = 0; k < 5; ++k) green.push_back({0, 0, 1}, {60, 130, 40});
  EXPECT_NE(filter_hsi(green).status.message.find("none red"), std::string::npos);
  ColorCloud broken = green;
  broken.rgb.pop_back();
  EXPECT_NE(filter_hsi(broken).status.message.find("malformed cloud"), std::string::npos);
  HsiFilterParams bad;
  bad.s_min = 300;
  EXPECT_NE(filter_hsi(green, bad).status.message.find("s_min must be in [0, 255], got 300"), std::string::npos);
  EXPECT_EQ(filter_hsi(green, bad).status.code, tinyline::common::StatusCode::InvalidArgument);
  EXPECT_THROW(HsiFilter{bad}, std::invalid_argument);
}
