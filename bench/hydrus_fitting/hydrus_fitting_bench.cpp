// SPDX-License-Identifier: Apache-2.0
// hydrus_fitting benchmarks. Per update with 4 sensors (4 x 256 pixels): the
// full CircleEstimator (fusion at each scan's joint angles, self-filter,
// weighted MSAC with viewpoints, incidence refit, bias removal) beside the
// plain Kasa fit on the same fused points (the cheapest fit there is, and
// biased), and the pieces in between. Two scenes: the open chain around a
// cylinder (no outliers), and the closed ring seeing its own links and
// clutter (about half the points are outliers before the self-filter). And
// the open chain flying past the cylinder at 0.125 m/s with the scans 30 ms
// apart, with the base's poses (each scan moved to the newest one's base
// frame) and, as its reference, without.
//
// Run: build/bench/hydrus_fitting/hydrus_fitting_bench
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include <tinyline/common/random.hpp>
#include "hydrus_fitting/estimator.hpp"
#include "hydrus_fitting/sequencer.hpp"
#include "planar_scene.hpp"

namespace hf = tinyline::hydrus_fitting;
namespace ev = tinyline::hydrus_fitting::eval;

namespace {

constexpr double kPi = std::numbers::pi;
constexpr int kUpdates = 32;  // distinct noise draws cycled through

struct Scene {
  hf::RobotModel model = hf::RobotModel::load(std::string(TINYLINE_SOURCE_DIR) + "/hydrus_fitting/config/hydrus4.yaml");
  hf::JointStateBuffer joints{model.joint_names()};
  std::vector<std::vector<ev::SyntheticScan>> updates;
  std::vector<std::vector<hf::ScanView>> views;
  std::vector<double> q;

  Scene(double joint_deg, const ev::PlanarWorld& world) {
    const double a = joint_deg * kPi / 180.0;
    q.assign(model.joint_names().size(), a);
    (void)joints.add(0, model.joint_names(), q);
    tinyline::common::SplitMixRandom rng(1);
    for (int u = 0; u < kUpdates; ++u) updates.push_back(ev::scan_all(model, q, world, {}, rng));
    for (const auto& u : updates) {
      std::vector<hf::ScanView> v;
      for (const auto& s : u) v.push_back({s.sensor, 0, s.angle_rad, s.range_m});
      views.push_back(std::move(v));
    }
  }
};

const Scene& open_chain() {
  static const Scene s(60.0, {{{{0.25, 0.433}, 0.15}}, {}, false});
  return s;
}
const Scene& closed_ring() {
  // Thin cylinder in the square; the sensors see the links across it and two small objects.
  static const Scene s(90.0, {{{{0.27, 0.24}, 0.07}, {{0.10, 0.40}, 0.03}, {{0.40, 0.10}, 0.03}}, {}, true});
  return s;
}

/// `correction`: the final refit's (CircleEstimatorParams::arc_correction);
/// kNone is the plain refit, the reference for its cost in the same run.
void run_estimator(benchmark::State& state, const Scene& s,
                   hf::ArcCorrection correction = hf::CircleEstimatorParams{}.arc_correction) {
  hf::CircleEstimatorParams p;
  p.arc_correction = correction;
  hf::CircleEstimator est(s.model, p);
  std::size_t k = 0;
  int points = 0;
  double hyp = 0, inl = 0, n = 0, end_weighted = 0;
  for (auto _ : state) {
    const auto e = est.estimate(s.views[k++ % kUpdates], s.joints);
    benchmark::DoNotOptimize(e.fit.circle.radius_m);
    points = e.points;
    hyp += e.fit.iterations;
    inl += e.fit.points_used;
    end_weighted += e.fit.end_weight_applied > 0.0 ? 1.0 : 0.0;
    ++n;
  }
  state.counters["points"] = points;
  state.counters["hypotheses"] = hyp / n;
  state.counters["inliers"] = inl / n;
  state.counters["end_weighted"] = end_weighted / n;  // fraction of updates with the end-weighted refit
}

/// The open chain with the base flying at 0.125 m/s past the cylinder: the
/// scans 30 ms apart (sequence mode), each of the cylinder where it was then,
/// and the base's poses, so the estimator moves each scan to the newest one's
/// base frame.
void run_estimator_moving_base(benchmark::State& state, bool use_poses, double speed_m_s = 0.125) {
  const Scene& s = open_chain();
  hf::JointStateBuffer joints(s.model.joint_names());
  hf::BasePoseBuffer poses;
  for (int i = 0; i <= 12; ++i) {
    const std::int64_t t = 10'000'000LL * i;
    (void)joints.add(t, s.model.joint_names(), s.q);
    (void)poses.add(t, {0.0, speed_m_s * 1e-9 * static_cast<double>(t)}, 0.0);
  }
  const int n = static_cast<int>(s.model.sensors().size());
  const Eigen::Vector2d fixed(0.25, 0.433 + speed_m_s * 0.03 * (n - 1));  // at (0.25, 0.433) for the newest scan
  tinyline::common::SplitMixRandom rng(1);
  std::vector<std::vector<ev::SyntheticScan>> scans(kUpdates);
  std::vector<std::vector<hf::ScanView>> views(kUpdates);
  for (int u = 0; u < kUpdates; ++u) {
    for (int i = 0; i < n; ++i) {
      const ev::PlanarWorld world{{hf::Circle{fixed - Eigen::Vector2d(0.0, speed_m_s * 0.03 * i), 0.15}}, {}, false};
      scans[u].push_back(ev::scan_all(s.model, s.q, world, {}, rng)[static_cast<std::size_t>(i)]);
    }
    for (int i = 0; i < n; ++i) {
      const auto& sc = scans[u][static_cast<std::size_t>(i)];
      views[u].push_back({sc.sensor, 30'000'000LL * i, sc.angle_rad, sc.range_m});
    }
  }
  hf::CircleEstimator est(s.model);
  std::size_t k = 0;
  int points = 0;
  bool moved = false;
  double hyp = 0, inl = 0, runs = 0;
  for (auto _ : state) {
    const auto e = est.estimate(views[k++ % kUpdates], joints, use_poses ? &poses : nullptr);
    benchmark::DoNotOptimize(e.fit.circle.radius_m);
    points = e.points;
    moved = e.base_motion_compensated || !use_poses;
    hyp += e.fit.iterations;
    inl += e.fit.points_used;
    ++runs;
  }
  state.counters["points"] = points;
  state.counters["hypotheses"] = hyp / runs;
  state.counters["inliers"] = inl / runs;
  if (!moved) state.SkipWithError("the scans were not moved by the base's motion");
}

void run_fusion_kasa(benchmark::State& state, const Scene& s) {
  hf::ScanFuser fuser(s.model);
  std::size_t k = 0;
  for (auto _ : state) {
    fuser.clear();
    for (const auto& v : s.views[k++ % kUpdates]) (void)fuser.add(v, s.joints);
    const auto f = hf::fit_circle_kasa(fuser.cloud().points_m());
    benchmark::DoNotOptimize(f.circle.radius_m);
  }
  state.counters["points"] = fuser.cloud().size();
}

/// The fused clouds, for the fit-only benchmarks.
std::vector<hf::FusedCloud> clouds(const Scene& s) {
  std::vector<hf::FusedCloud> c;
  hf::ScanFuser fuser(s.model);
  for (const auto& v : s.views) {
    fuser.clear();
    for (const auto& x : v) (void)fuser.add(x, s.joints);
    c.push_back(fuser.cloud());
  }
  return c;
}

}  // namespace

// ---- the headline figure: fusion + fit per update, 4 sensors, one core.
static void BM_Update_Estimator_OpenChain(benchmark::State& s) { run_estimator(s, open_chain()); }
BENCHMARK(BM_Update_Estimator_OpenChain)->Unit(benchmark::kMicrosecond);
static void BM_Update_Estimator_OpenChain_BaseMotion(benchmark::State& s) { run_estimator_moving_base(s, true); }
BENCHMARK(BM_Update_Estimator_OpenChain_BaseMotion)->Unit(benchmark::kMicrosecond);
static void BM_Update_Estimator_OpenChain_MovingNoPoses(benchmark::State& s) { run_estimator_moving_base(s, false); }
BENCHMARK(BM_Update_Estimator_OpenChain_MovingNoPoses)->Unit(benchmark::kMicrosecond);
// The compensation's own cost: a base standing still, its poses given.
static void BM_Update_Estimator_OpenChain_StaticWithPoses(benchmark::State& s) {
  run_estimator_moving_base(s, true, 0.0);
}
BENCHMARK(BM_Update_Estimator_OpenChain_StaticWithPoses)->Unit(benchmark::kMicrosecond);
static void BM_Update_Estimator_OpenChain_PlainRefit(benchmark::State& s) {
  run_estimator(s, open_chain(), hf::ArcCorrection::kNone);
}
BENCHMARK(BM_Update_Estimator_OpenChain_PlainRefit)->Unit(benchmark::kMicrosecond);
static void BM_Update_FusionKasa_OpenChain(benchmark::State& s) { run_fusion_kasa(s, open_chain()); }
BENCHMARK(BM_Update_FusionKasa_OpenChain)->Unit(benchmark::kMicrosecond);
static void BM_Update_Estimator_ClosedRingWithOutliers(benchmark::State& s) { run_estimator(s, closed_ring()); }
BENCHMARK(BM_Update_Estimator_ClosedRingWithOutliers)->Unit(benchmark::kMicrosecond);
static void BM_Update_Estimator_ClosedRingWithOutliers_PlainRefit(benchmark::State& s) {
  run_estimator(s, closed_ring(), hf::ArcCorrection::kNone);
}
BENCHMARK(BM_Update_Estimator_ClosedRingWithOutliers_PlainRefit)->Unit(benchmark::kMicrosecond);
static void BM_Update_FusionKasa_ClosedRingWithOutliers(benchmark::State& s) { run_fusion_kasa(s, closed_ring()); }
BENCHMARK(BM_Update_FusionKasa_ClosedRingWithOutliers)->Unit(benchmark::kMicrosecond);

// ---- the second-order correction where it acts: 100 points on a 120 deg
// arc of a 15 cm circle with 19.6 mm noise (the KCR study's cell), 64 noise
// draws cycled; Hyper + geometric LM with the essential bias removed, without
// and with the correction (end-weighted refit and mode shift).
static void run_arc_fit(benchmark::State& state, hf::ArcCorrection correction) {
  static const std::vector<Eigen::Matrix2Xd> draws = [] {
    std::vector<Eigen::Matrix2Xd> d;
    tinyline::common::SplitMixRandom rng(9);
    for (int t = 0; t < 64; ++t) {
      Eigen::Matrix2Xd p(2, 100);
      for (int i = 0; i < 100; ++i) {
        const double a = std::numbers::pi / 2 + (i / 99.0 - 0.5) * 2.0 * std::numbers::pi / 3.0;
        p.col(i) =
            Eigen::Vector2d(0.15 * std::cos(a) + 0.019593 * rng.normal(), 0.15 * std::sin(a) + 0.019593 * rng.normal());
      }
      d.push_back(p);
    }
    return d;
  }();
  hf::RefineParams rp;
  rp.remove_radius_bias = true;
  rp.correction = correction;
  std::size_t k = 0;
  double weighted = 0, n = 0;
  for (auto _ : state) {
    const auto f = hf::fit_circle(draws[k++ % draws.size()], rp);
    benchmark::DoNotOptimize(f.circle.radius_m);
    weighted += f.end_weight_applied > 0.0 ? 1.0 : 0.0;
    ++n;
  }
  state.counters["end_weighted"] = weighted / n;
}
static void BM_Piece_Arc120_Sigma19mm_Plain(benchmark::State& s) { run_arc_fit(s, hf::ArcCorrection::kNone); }
BENCHMARK(BM_Piece_Arc120_Sigma19mm_Plain)->Unit(benchmark::kMicrosecond);
static void BM_Piece_Arc120_Sigma19mm_SecondOrder(benchmark::State& s) {
  run_arc_fit(s, hf::ArcCorrection::kSecondOrder);
}
BENCHMARK(BM_Piece_Arc120_Sigma19mm_SecondOrder)->Unit(benchmark::kMicrosecond);

// ---- the pieces, on the open chain's fused clouds.
static void BM_Piece_FusionOnly(benchmark::State& state) {
  const Scene& s = open_chain();
  hf::ScanFuser fuser(s.model);
  std::size_t k = 0;
  for (auto _ : state) {
    fuser.clear();
    for (const auto& v : s.views[k++ % kUpdates]) (void)fuser.add(v, s.joints);
    benchmark::DoNotOptimize(fuser.cloud().xy_m.data());
  }
}
BENCHMARK(BM_Piece_FusionOnly)->Unit(benchmark::kMicrosecond);

template <class Fit>
void run_fit(benchmark::State& state, Fit fit) {
  static const auto c = clouds(open_chain());
  std::size_t k = 0;
  for (auto _ : state) {
    const auto& cl = c[k++ % c.size()];
    const auto f = fit(cl);
    benchmark::DoNotOptimize(f.circle.radius_m);
  }
}
static void BM_Piece_Kasa(benchmark::State& s) {
  run_fit(s, [](const hf::FusedCloud& c) { return hf::fit_circle_kasa(c.points_m()); });
}
BENCHMARK(BM_Piece_Kasa)->Unit(benchmark::kMicrosecond);
static void BM_Piece_Hyper(benchmark::State& s) {
  run_fit(s, [](const hf::FusedCloud& c) { return hf::fit_circle_hyper(c.points_m()); });
}
BENCHMARK(BM_Piece_Hyper)->Unit(benchmark::kMicrosecond);
static void BM_Piece_HyperPlusGeometric(benchmark::State& s) {
  run_fit(s, [](const hf::FusedCloud& c) { return hf::fit_circle(c.points_m(), {}, c.sigma_m); });
}
BENCHMARK(BM_Piece_HyperPlusGeometric)->Unit(benchmark::kMicrosecond);
static void BM_Piece_RobustWithViewpoints(benchmark::State& s) {
  run_fit(s, [](const hf::FusedCloud& c) {
    return hf::fit_circle_robust(c.points_m(), {}, c.sigma_m, {c.views, c.view_of_point});
  });
}
BENCHMARK(BM_Piece_RobustWithViewpoints)->Unit(benchmark::kMicrosecond);

// ---- the sequencer: interference graph + colouring + schedule for 4 sensors.
static void BM_Sequencer_Rebuild(benchmark::State& state) {
  const Scene& s = open_chain();
  const hf::Circle object{{0.25, 0.433}, 0.15};
  std::size_t k = 0;
  for (auto _ : state) {
    hf::Sequencer seq(s.model);
    std::vector<double> q = s.q;
    q[0] += 1e-3 * static_cast<double>(k++ % 7);
    benchmark::DoNotOptimize(seq.update(q, object));
  }
}
BENCHMARK(BM_Sequencer_Rebuild)->Unit(benchmark::kMicrosecond);

BENCHMARK_MAIN();
