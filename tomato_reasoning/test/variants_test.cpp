// SPDX-License-Identifier: Apache-2.0
// The evaluation's OpenCV segmentation variants (eval/src/variants.cpp): the
// image mask with nothing added is the per-point HSI filter, so the
// comparison in docs/tomato_reasoning.md measures only what OpenCV adds.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/eval/variants.hpp"

namespace tr = tinyline::tomato_reasoning;
namespace te = tinyline::tomato_reasoning::eval;

TEST(Variants, TheImageMaskWithoutMorphologyIsThePerPointFilter) {
  const te::Scenario s = te::make_scenario(tinyline::sim::TrussClass::kB, 4);
  const auto run = [&](const std::string& name) { return te::make_variant(name, te::variant_params(name))->run(s); };
  const tr::PipelineResult a = run("default"), b = run("opencv_hsi"), c = run("opencv_hsi:open=5:area=400");
  ASSERT_TRUE(a.status.ok()) << a.status.message;
  ASSERT_EQ(b.tomatoes.size(), a.tomatoes.size());
  EXPECT_EQ(b.red_points, a.red_points);
  for (std::size_t i = 0; i < a.tomatoes.size(); ++i)
    EXPECT_EQ(b.tomatoes[i].fit.sphere.centre, a.tomatoes[i].fit.sphere.centre) << i;
  EXPECT_LT(c.red_points, a.red_points);  // opening and dropping small parts remove pixels
  EXPECT_GT(c.red_points, a.red_points / 2);
}

TEST(Variants, OpenCvVariantNamesParseOrSayWhatIsWrong) {
  EXPECT_NO_THROW((void)te::make_variant("opencv_hsv:hh=12:s=90:vmin=20:vmax=240:open=3:close=5:area=50", {}));
  EXPECT_THAT([] { (void)te::make_variant("opencv_hsv:foo=3", {}); },
              ::testing::ThrowsMessage<std::invalid_argument>(::testing::HasSubstr("'foo=3' is not one of")));
}
