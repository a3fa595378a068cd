// SPDX-License-Identifier: Apache-2.0
// laser_clustering benchmarks. Per 256-pixel scan: the whole two-stage
// clustering + pedicel finding (the fast path), against the same two DBSCAN
// passes on the same points through the FLANN path and the brute-force
// O(n^2) algorithm. General DBSCAN on 3-D clouds up to 100,000 points.
// scikit-learn's side of the comparison runs in side_by_side.py, on points
// this binary dumps with --dump_points=FILE.
//
// Run: build/bench/laser_clustering/laser_clustering_bench
//      .venv/bin/python bench/laser_clustering/side_by_side.py --build build
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>
#include <fmt/format.h>
#include <tinyline/common/files.hpp>

#include "bench_scenes.hpp"
#include "laser_clustering/dbscan.hpp"
#include "laser_clustering/pedicel_finder.hpp"
#include "laser_clustering/tomato_registration.hpp"
#include "laser_clustering/two_stage.hpp"

namespace lc = tinyline::laser_clustering;

namespace {

constexpr int kScans = 64;

const std::vector<lc::LineScan>& scans() {
  static const auto s = lc::bench::pedicel_scans(kScans);
  return s;
}

const std::vector<Eigen::MatrixXd>& scan_points() {
  static const auto p = [] {
    std::vector<Eigen::MatrixXd> v;
    for (const auto& s : scans()) v.push_back(lc::to_points({s.angle_rad, s.range_m, {}, {}}));
    return v;
  }();
  return p;
}

void BM_TwoStagePlusPedicel(benchmark::State& state) {
  lc::LineScanClusterer clusterer;
  lc::TwoStageResult objects;  // kept: as a node's loop would
  const lc::PedicelFinderParams finder;
  std::size_t k = 0;
  for (auto _ : state) {
    const auto& s = scans()[k++ % kScans];
    clusterer.run(s, objects);
    const auto pedicel = lc::find_pedicel(s, objects, finder);
    benchmark::DoNotOptimize(pedicel.lateral_offset_m);
  }
}
BENCHMARK(BM_TwoStagePlusPedicel);

void BM_TwoStageOnly(benchmark::State& state) {
  lc::LineScanClusterer clusterer;
  lc::TwoStageResult objects;
  std::size_t k = 0;
  for (auto _ : state) {
    clusterer.run(scans()[k++ % kScans], objects);
    benchmark::DoNotOptimize(objects.clusters.data());
  }
}
BENCHMARK(BM_TwoStageOnly);

// The tomato look's registration: once per pick (not per scan), on a scan
// through four tomatoes with the vision's layout 3 cm off. Beside it in the
// same run: BM_TwoStagePlusPedicel, the per-scan work, and the sensor's
// frame period (10 ms at 100 Hz) is the budget it must fit.
void BM_RegisterTomatoes(benchmark::State& state) {
  const std::vector<lc::test::Disc> truth{{-0.11, 0.23, 0.028, 6.0, 1},
                                          {-0.04, 0.21, 0.033, 6.0, 2},
                                          {0.035, 0.24, 0.026, 6.0, 3},
                                          {0.10, 0.22, 0.031, 6.0, 4}};
  lc::test::SynthParams sp;
  sp.wall_z_m = 0.45;
  sp.noise_sd_m = 0.003;
  const auto scan = lc::test::synth_scan(truth, sp).scan;
  std::vector<lc::ExpectedTomato> expected;
  for (const auto& d : truth) expected.push_back({Eigen::Vector3d(d.x_m - 0.03, 0.0, d.z_m + 0.01), d.radius_m});
  const lc::TomatoRegistrationParams params;
  for (auto _ : state) {
    const auto r = lc::register_tomatoes(scan, expected, params);
    if (!r.status.ok()) state.SkipWithError(r.status.message.c_str());
    benchmark::DoNotOptimize(r.shift_xz_m.data());
  }
}
BENCHMARK(BM_RegisterTomatoes)->Unit(benchmark::kMicrosecond);

// One ordered-scan DBSCAN pass with the stage-1 parameters.
void BM_OrderedScanDbscanStage1(benchmark::State& state) {
  lc::OrderedScanDbscan d;
  lc::DbscanResult r;
  const lc::TwoStageParams p;
  std::size_t k = 0;
  for (auto _ : state) {
    const auto& s = scans()[k++ % kScans];
    d.run({s.angle_rad, s.range_m, {}, {}}, p.groups, r);
    benchmark::DoNotOptimize(r.labels.data());
  }
}
BENCHMARK(BM_OrderedScanDbscanStage1);

// The two DBSCAN passes (stage-1 and stage-3 parameters on the scan's
// points), through the general searches: what the pipeline would cost
// without the ordered-scan fast path.
void BM_FlannDbscanTwoPasses(benchmark::State& state) {
  const lc::TwoStageParams p;
  std::size_t k = 0;
  for (auto _ : state) {
    const auto& pts = scan_points()[k++ % kScans];
    const auto a = lc::dbscan(pts, p.groups);
    const auto b = lc::dbscan(pts, p.objects);
    benchmark::DoNotOptimize(a.labels.data());
    benchmark::DoNotOptimize(b.labels.data());
  }
}
BENCHMARK(BM_FlannDbscanTwoPasses);

void BM_BruteForceDbscanTwoPasses(benchmark::State& state) {
  const lc::TwoStageParams p;
  std::size_t k = 0;
  for (auto _ : state) {
    const auto& pts = scan_points()[k++ % kScans];
    const auto a = lc::dbscan_brute_force(pts, p.groups);
    const auto b = lc::dbscan_brute_force(pts, p.objects);
    benchmark::DoNotOptimize(a.labels.data());
    benchmark::DoNotOptimize(b.labels.data());
  }
}
BENCHMARK(BM_BruteForceDbscanTwoPasses);

// General DBSCAN on 3-D surface clouds: eps 1 cm, min 5 (about 16 neighbours per point).
constexpr double kCloudEps = 0.01;
constexpr int kCloudMin = 5;

const Eigen::MatrixXd& cloud(int n) {
  static std::vector<std::pair<int, Eigen::MatrixXd>> cache;
  for (const auto& [k, c] : cache)
    if (k == n) return c;
  cache.emplace_back(n, lc::bench::surface_cloud(n));
  return cache.back().second;
}

void BM_FlannDbscan3D(benchmark::State& state) {
  const auto& c = cloud(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    const auto r = lc::dbscan(c, {kCloudEps, kCloudMin});
    benchmark::DoNotOptimize(r.labels.data());
  }
  state.SetComplexityN(state.range(0));
}
BENCHMARK(BM_FlannDbscan3D)->Arg(1000)->Arg(10000)->Arg(100000)->Unit(benchmark::kMillisecond)->Complexity();

void BM_BruteForceDbscan3D(benchmark::State& state) {
  const auto& c = cloud(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    const auto r = lc::dbscan_brute_force(c, {kCloudEps, kCloudMin});
    benchmark::DoNotOptimize(r.labels.data());
  }
  state.SetComplexityN(state.range(0));
}
BENCHMARK(BM_BruteForceDbscan3D)->Arg(1000)->Arg(10000)->Unit(benchmark::kMillisecond)->Iterations(2);

// Writes the benchmark's inputs for side_by_side.py: every scan's points and
// the 100k cloud, in hex floats (exact), with the parameters used.
void dump_points(const std::string& path) {
  tinyline::files::AtomicStream f(path, tinyline::files::named("points file"));
  const lc::TwoStageParams p;
  f << fmt::format("params {:a} {} {:a} {} {:a} {}\n", p.groups.eps, p.groups.min_points, p.objects.eps,
                   p.objects.min_points, kCloudEps, kCloudMin);
  for (const auto& pts : scan_points()) {
    int valid = 0;
    for (Eigen::Index i = 0; i < pts.cols(); ++i) valid += pts.col(i).allFinite();
    f << "scan " << valid << "\n";
    for (Eigen::Index i = 0; i < pts.cols(); ++i) {
      if (pts.col(i).allFinite()) f << fmt::format("{:a} {:a}\n", pts(0, i), pts(1, i));
    }
  }
  const auto& c = cloud(100000);
  f << "cloud " << c.cols() << "\n";
  for (Eigen::Index i = 0; i < c.cols(); ++i) f << fmt::format("{:a} {:a} {:a}\n", c(0, i), c(1, i), c(2, i));
  f.commit();
}

}  // namespace

int main(int argc, char** argv) {
  std::vector<char*> args;
  for (int i = 0; i < argc; ++i) {
    if (std::strncmp(argv[i], "--dump_points=", 14) == 0) {
      try {
        dump_points(argv[i] + 14);
      } catch (const tinyline::files::FileError& e) {
        std::fprintf(stderr, "laser_clustering_bench: %s\n", e.what());
        return 1;
      }
      return 0;
    }
    args.push_back(argv[i]);
  }
  int n = static_cast<int>(args.size());
  benchmark::Initialize(&n, args.data());
  if (benchmark::ReportUnrecognizedArguments(n, args.data())) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
