// SPDX-License-Identifier: Apache-2.0
// Two-stage line-scan clustering (4.4.2) on hand-made scans.
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <set>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "laser_clustering/two_stage.hpp"
#include "synthetic_scan.hpp"

namespace lc = tinyline::laser_clustering;
using lc::test::Disc;
using lc::test::synth_scan;
using lc::test::SynthParams;
using ::testing::HasSubstr;

namespace {

// The final object that holds most pixels of ground-truth id `id`.
int object_of(const lc::TwoStageResult& r, const std::vector<int>& truth, int id) {
  std::map<int, int> votes;
  for (std::size_t i = 0; i < truth.size(); ++i) {
    if (truth[i] == id && r.labels[i] >= 0) ++votes[r.labels[i]];
  }
  int best = -1, n = 0;
  for (auto [l, c] : votes) {
    if (c > n) {
      best = l;
      n = c;
    }
  }
  return best;
}

}  // namespace

TEST(TwoStage, PedicelInFrontOfAWallIsOneNarrowObject) {
  SynthParams sp;
  sp.wall_z_m = 0.35;
  sp.seed = 3;
  const auto s = synth_scan({{0.01, 0.15, 0.003, 6.0, 1}}, sp);
  const auto r = lc::cluster_line_scan(s.scan);
  ASSERT_TRUE(r.status.ok()) << r.status.message;
  const int ped = object_of(r, s.truth, 1);
  ASSERT_GE(ped, 0);
  const auto& c = r.clusters[static_cast<std::size_t>(ped)];
  EXPECT_NEAR(c.width_m, 0.006, 0.0015);
  EXPECT_NEAR(c.mean_range_m, 0.15 - 0.002, 0.003);  // the rod's front surface
  EXPECT_NEAR(c.centroid_xz_m.x(), 0.01, 0.001);
  EXPECT_FALSE(c.touches_fov_edge);
  EXPECT_FALSE(c.occluded_low);
  EXPECT_FALSE(c.occluded_high);
  // No wall pixel in the pedicel's object and vice versa.
  for (std::size_t i = 0; i < s.truth.size(); ++i) {
    if (r.labels[i] == ped) {
      EXPECT_EQ(s.truth[i], 1) << "pixel " << i;
    }
  }
}

TEST(TwoStage, DragTrailLeavesNoSpuriousObjectAndDoesNotWidenThePedicel) {
  // Three pedicels with strong emitter-side drag (12, 3 and 0.75 cm on their
  // three edge pixels) before a wall.
  SynthParams sp;
  sp.wall_z_m = 0.45;
  sp.drag_m = 0.12;
  sp.drag_px = 3;
  sp.noise_sd_m = 0.0015;
  int spurious = 0, pedicels_found = 0, dropped = 0;
  for (unsigned seed = 1; seed <= 40; ++seed) {
    sp.seed = seed;
    const auto s =
        synth_scan({{-0.05, 0.16, 0.003, 6.0, 1}, {0.0, 0.14, 0.003, 6.0, 2}, {0.045, 0.18, 0.003, 6.0, 3}}, sp);
    const auto r = lc::cluster_line_scan(s.scan);
    ASSERT_TRUE(r.status.ok()) << r.status.message;
    dropped += r.num_edge_dropped;
    std::set<int> real;
    for (int id = 0; id <= 3; ++id) real.insert(object_of(r, s.truth, id));
    for (const auto& c : r.clusters) {
      if (!real.count(c.id) && c.mean_range_m < 0.40) ++spurious;
    }
    for (int id = 1; id <= 3; ++id) {
      const int o = object_of(r, s.truth, id);
      // Dragged edge pixels leave, so the width may shrink by a pixel or two
      // (0.7 mm each here), but never grows.
      if (o >= 0) {
        const double w = r.clusters[static_cast<std::size_t>(o)].width_m;
        pedicels_found += w > 0.0033 && w < 0.0068;
      }
    }
  }
  EXPECT_EQ(spurious, 0);
  EXPECT_GE(pedicels_found, 115) << "of 120 pedicels";
  EXPECT_GT(dropped, 40) << "the edge filter should peel some dragged pixels";
}

TEST(TwoStage, PedicelTouchingATomatoIsSeparatedInsideOneGroup) {
  // A pedicel 1.5 cm in front of a tomato's surface: one stage-1 group, two objects.
  SynthParams sp;
  sp.noise_sd_m = 0.001;
  sp.seed = 5;
  const auto s = synth_scan({{0.0, 0.14, 0.003, 6.0, 1}, {0.0, 0.19, 0.032, 6.0, 2}}, sp);
  const auto r = lc::cluster_line_scan(s.scan);
  ASSERT_TRUE(r.status.ok()) << r.status.message;
  const int ped = object_of(r, s.truth, 1), tom = object_of(r, s.truth, 2);
  ASSERT_GE(ped, 0);
  ASSERT_GE(tom, 0);
  EXPECT_NE(ped, tom);
  EXPECT_EQ(r.clusters[static_cast<std::size_t>(ped)].group, r.clusters[static_cast<std::size_t>(tom)].group)
      << "stage 1 keeps touching objects together";
  EXPECT_NEAR(r.clusters[static_cast<std::size_t>(ped)].width_m, 0.006, 0.0015);
  // The tomato is seen on both sides of the pedicel; each side is occluded
  // towards the pedicel.
  int tomato_parts = 0;
  for (const auto& c : r.clusters) {
    if (c.mean_range_m > 0.16 && c.mean_range_m < 0.19 && c.width_m > 0.01) {
      ++tomato_parts;
      EXPECT_TRUE(c.occluded_low || c.occluded_high);
    }
  }
  EXPECT_EQ(tomato_parts, 2);
}

TEST(TwoStage, SmoothingReducesNoiseWithoutCrossingSteps) {
  SynthParams sp;
  sp.wall_z_m = 0.30;
  sp.noise_sd_m = 0.003;
  sp.seed = 9;
  const auto s = synth_scan({}, sp);
  const auto r = lc::cluster_line_scan(s.scan);
  ASSERT_TRUE(r.status.ok());
  double raw = 0.0, smooth = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < s.scan.size(); ++i) {
    if (r.fate[i] != lc::PixelFate::kKept) continue;
    const double truth = 0.30 / std::cos(s.scan.angle_rad[i]);
    raw += std::pow(s.scan.range_m[i] - truth, 2);
    smooth += std::pow(r.smoothed_range_m[i] - truth, 2);
    ++n;
  }
  ASSERT_GT(n, 200);
  EXPECT_LT(std::sqrt(smooth / n), 0.6 * std::sqrt(raw / n));
  // A 5 cm depth step is kept sharp: no smoothed point lands in the gap.
  lc::LineScan step = s.scan;
  std::mt19937 rng(1);
  std::normal_distribution<double> g(0.0, 0.003);
  for (std::size_t i = 0; i < step.size(); ++i) step.range_m[i] = (i < 128 ? 0.20 : 0.25) + g(rng);
  const auto q = lc::cluster_line_scan(step);
  for (std::size_t i = 0; i < step.size(); ++i) {
    if (q.fate[i] == lc::PixelFate::kKept) {
      EXPECT_FALSE(q.smoothed_range_m[i] > 0.215 && q.smoothed_range_m[i] < 0.235) << "pixel " << i;
    }
  }
}

TEST(TwoStage, FieldOfViewEdgeIsFlagged) {
  SynthParams sp;
  sp.seed = 2;
  // A rod right at the left edge of the 70 degree fan.
  const double a = -35.0 * std::numbers::pi / 180.0;
  const auto s = synth_scan({{0.15 * std::sin(a) + 0.001, 0.15 * std::cos(a), 0.003, 6.0, 1}}, sp);
  const auto r = lc::cluster_line_scan(s.scan);
  ASSERT_TRUE(r.status.ok());
  ASSERT_EQ(r.clusters.size(), 1u);
  EXPECT_TRUE(r.clusters[0].touches_fov_edge);
  EXPECT_LT(r.clusters[0].width_m, 0.006);
}

TEST(TwoStage, EmptyAllInvalidAndMalformedScans) {
  const auto empty = lc::cluster_line_scan({});
  EXPECT_TRUE(empty.status.ok());
  EXPECT_EQ(empty.note, "empty scan");
  EXPECT_TRUE(empty.clusters.empty());

  lc::LineScan nan_scan;
  for (int i = 0; i < 256; ++i) {
    nan_scan.angle_rad.push_back(0.001 * i);
    nan_scan.range_m.push_back(std::numeric_limits<double>::quiet_NaN());
  }
  const auto all_bad = lc::cluster_line_scan(nan_scan);
  EXPECT_TRUE(all_bad.status.ok());
  EXPECT_EQ(all_bad.note, "no valid pixels");
  EXPECT_TRUE(all_bad.clusters.empty());
  for (const auto l : all_bad.labels) EXPECT_EQ(l, lc::kInvalid);

  lc::LineScan mismatch = nan_scan;
  mismatch.range_m.pop_back();
  const auto m = lc::cluster_line_scan(mismatch);
  EXPECT_EQ(m.status.code, tinyline::StatusCode::InvalidArgument);
  EXPECT_THAT(m.status.message, HasSubstr("256 angles but 255 ranges"));

  lc::LineScan backwards = nan_scan;
  backwards.angle_rad[100] = backwards.angle_rad[50];
  const auto b = lc::cluster_line_scan(backwards);
  EXPECT_FALSE(b.status.ok());
  EXPECT_THAT(b.status.message, HasSubstr("pixel 100"));

  lc::LineScan refl = nan_scan;
  refl.reflectance.assign(3, 1.0);
  EXPECT_THAT(lc::cluster_line_scan(refl).status.message, HasSubstr("256 ranges but 3 reflectance"));
}

TEST(TwoStage, RejectsBadParameters) {
  lc::TwoStageParams p;
  p.groups.eps = 0.0;
  EXPECT_THAT(lc::cluster_line_scan({}, p).status.message, HasSubstr("groups: DbscanParams.eps"));
  p = {};
  p.objects.min_points = 0;
  EXPECT_THAT(lc::cluster_line_scan({}, p).status.message, HasSubstr("objects: DbscanParams.min_points"));
  p = {};
  p.edge.step_m = std::numeric_limits<double>::quiet_NaN();
  const auto r = lc::cluster_line_scan({}, p);
  EXPECT_FALSE(r.status.ok());
  EXPECT_THAT(r.status.message, HasSubstr("edge: edge_step_m must be in [0, 1], got nan"));
  p = {};
  p.edge.reference_px = 0;
  EXPECT_THAT(lc::validate(p).message, HasSubstr("edge_reference_px must be in [1, 16], got 0"));
  p.edge.reference_px = 17;  // the filter's buffers hold 16
  EXPECT_FALSE(lc::validate(p).ok());
}

TEST(TwoStage, GroupsKeepStageThreeInsideThem) {
  // The fast path's group ids: pixels of different groups never join, as if
  // run group by group.
  SynthParams sp;
  sp.wall_z_m = 0.3;
  sp.seed = 4;
  const auto s = synth_scan({{0.0, 0.2, 0.01, 6.0, 1}}, sp);
  std::vector<int> group(s.scan.size());
  for (std::size_t i = 0; i < group.size(); ++i) group[i] = static_cast<int>(i / 64);  // four arbitrary groups
  const auto r = lc::dbscan_ordered_scan({s.scan.angle_rad, s.scan.range_m, {}, group}, {0.01, 2});
  ASSERT_TRUE(r.status.ok());
  // The brute-force reference with a group coordinate 1 km apart per group.
  Eigen::MatrixXd p(3, static_cast<Eigen::Index>(group.size()));
  p.topRows(2) = lc::to_points({s.scan.angle_rad, s.scan.range_m, {}, {}});
  for (std::size_t i = 0; i < group.size(); ++i) p(2, static_cast<Eigen::Index>(i)) = 1000.0 * group[i];
  const auto ref = lc::dbscan_brute_force(p, {0.01, 2});
  EXPECT_EQ(r.labels, ref.labels);
  EXPECT_EQ(r.is_core, ref.is_core);
  for (std::size_t i = 1; i < group.size(); ++i) {
    if (group[i] != group[i - 1] && r.labels[i] >= 0 && r.labels[i - 1] >= 0) {
      EXPECT_NE(r.labels[i], r.labels[i - 1]);
    }
  }
}

TEST(TwoStage, AReusedResultIsTheSameAsAFreshOne) {
  // A node keeps one result and one clusterer scan after scan: every field
  // must come out as a fresh run's, also after a malformed scan and after a
  // scan with more objects than the next.
  lc::LineScanClusterer reused_clusterer;
  lc::TwoStageResult kept;
  std::vector<lc::LineScan> scans;
  for (unsigned seed = 1; seed <= 6; ++seed) {
    SynthParams sp;
    sp.seed = seed;
    sp.drag_m = 0.05;
    sp.wall_z_m = 0.3 + 0.05 * seed;
    std::vector<Disc> discs{{0.01 * seed - 0.03, 0.12, 0.003, 6.0, 1}};
    if (seed % 2) discs.push_back({-0.04, 0.2, 0.03, 6.0, 2});
    scans.push_back(synth_scan(discs, sp).scan);
    if (seed == 3) {  // a malformed one in between
      lc::LineScan bad = scans.back();
      bad.range_m.pop_back();
      scans.push_back(bad);
    }
  }
  for (std::size_t k = 0; k < scans.size(); ++k) {
    SCOPED_TRACE(k);
    reused_clusterer.run(scans[k], kept);
    const lc::TwoStageResult fresh = lc::cluster_line_scan(scans[k]);
    EXPECT_EQ(kept.status.code, fresh.status.code);
    EXPECT_EQ(kept.status.message, fresh.status.message);
    EXPECT_EQ(kept.note, fresh.note);
    EXPECT_EQ(kept.group_labels, fresh.group_labels);
    EXPECT_EQ(kept.fate, fresh.fate);
    EXPECT_EQ(kept.labels, fresh.labels);
    ASSERT_EQ(kept.smoothed_range_m.size(), fresh.smoothed_range_m.size());
    for (std::size_t i = 0; i < kept.smoothed_range_m.size(); ++i) {
      const double a = kept.smoothed_range_m[i], b = fresh.smoothed_range_m[i];
      EXPECT_TRUE((std::isnan(a) && std::isnan(b)) || a == b) << "pixel " << i;
    }
    EXPECT_EQ(kept.num_groups, fresh.num_groups);
    EXPECT_EQ(kept.num_edge_dropped, fresh.num_edge_dropped);
    ASSERT_EQ(kept.clusters.size(), fresh.clusters.size());
    for (std::size_t c = 0; c < kept.clusters.size(); ++c) {
      const auto &a = kept.clusters[c], &b = fresh.clusters[c];
      EXPECT_EQ(a.first_pixel, b.first_pixel);
      EXPECT_EQ(a.last_pixel, b.last_pixel);
      EXPECT_EQ(a.num_points, b.num_points);
      EXPECT_EQ(a.centroid_xz_m, b.centroid_xz_m);  // bit for bit
      EXPECT_EQ(a.mean_range_m, b.mean_range_m);
      EXPECT_EQ(a.range_sd_m, b.range_sd_m);
      EXPECT_EQ(a.width_m, b.width_m);
      EXPECT_TRUE((std::isnan(a.mean_reflectance) && std::isnan(b.mean_reflectance)) ||
                  a.mean_reflectance == b.mean_reflectance);
      EXPECT_EQ(a.occluded_low, b.occluded_low);
      EXPECT_EQ(a.occluded_high, b.occluded_high);
    }
    if (k == 3) {
      EXPECT_FALSE(kept.status.ok()) << "the malformed scan";
    }
  }
}
