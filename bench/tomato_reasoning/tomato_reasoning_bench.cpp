// The tomato pipeline per VGA frame, stage by stage, beside a plain PCL chain
// with default settings on the same simulated clouds (docs/benchmarks.md):
//
//   plain PCL: ConditionalRemoval with PackedHSIComparison (the thesis's HSI
//   ranges) -> EuclideanClusterExtraction (6 cm, the closest cluster) ->
//   MovingLeastSquares (1.2 cm, normals) -> SACSegmentation SACMODEL_SPHERE
//   (RANSAC, 4 mm, radius 2.5-4 cm), repeated on the remaining points until
//   fewer than 40 remain or no model is found.
//
// Both report per-stage milliseconds and the detections (a sphere within
// 1 cm of a true centre) as counters, so speed is compared at the detection
// each reaches.
//
//   build/bench/tomato_reasoning/tomato_reasoning_bench --benchmark_min_time=2
#include <algorithm>
#include <chrono>
#include <vector>

#include <benchmark/benchmark.h>

#include <pcl/ModelCoefficients.h>
#include <pcl/filters/conditional_removal.h>
#include <pcl/filters/extract_indices.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/extract_clusters.h>
#include <pcl/segmentation/sac_segmentation.h>
#include <pcl/surface/mls.h>

#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/pipeline.hpp"

using namespace tinyline;
using namespace tinyline::tomato_reasoning;

namespace {

struct Frame {
  eval::Scenario scenario;
  pcl::PointCloud<pcl::PointXYZRGB>::Ptr pcl_cloud;
};

const std::vector<Frame>& frames(char cls) {
  static std::vector<Frame> a, b, c;
  auto& out = cls == 'A' ? a : cls == 'B' ? b : c;
  if (out.empty()) {
    for (std::uint64_t seed = 1; seed <= 8; ++seed) {
      Frame f{eval::make_scenario(*sim::parse_truss_class(std::string(1, cls)), seed), nullptr};
      const ColorCloud& cc = f.scenario.cloud();
      f.pcl_cloud.reset(new pcl::PointCloud<pcl::PointXYZRGB>(std::uint32_t(cc.width), std::uint32_t(cc.height)));
      for (std::size_t i = 0; i < cc.size(); ++i) {
        auto& p = (*f.pcl_cloud)[i];
        p.x = cc.xyz[i].x();
        p.y = cc.xyz[i].y();
        p.z = cc.xyz[i].z();
        p.r = cc.rgb[i][0];
        p.g = cc.rgb[i][1];
        p.b = cc.rgb[i][2];
      }
      f.pcl_cloud->is_dense = false;
      out.push_back(std::move(f));
    }
  }
  return out;
}

int matched(const eval::Scenario& s, const std::vector<Eigen::Vector3d>& centres) {
  int n = 0;
  for (const auto& t : s.truth)
    n += std::any_of(centres.begin(), centres.end(), [&](const Eigen::Vector3d& c) { return (c - t.centre_m).norm() <= 0.01; });
  return n;
}

// Per-stage times and detections over the frames one benchmark ran, reported
// as its counters under the same names for both pipelines.
struct FrameTally {
  double hsi = 0, branch = 0, smooth = 0, spheres = 0, reasoning = 0;  // [ms]
  long detected = 0, truth = 0, frames = 0, found = 0;

  void add_detections(const eval::Scenario& s, const std::vector<Eigen::Vector3d>& centres) {
    detected += matched(s, centres);
    found += long(centres.size());
    truth += long(s.truth.size());
    ++frames;
  }
  void report(benchmark::State& state, bool with_reasoning) const {
    const double n = double(std::max(1L, frames));
    state.counters["hsi_ms"] = hsi / n;
    state.counters["branch_ms"] = branch / n;
    state.counters["smoothing_ms"] = smooth / n;
    state.counters["spheres_ms"] = spheres / n;
    if (with_reasoning) state.counters["reasoning_ms"] = reasoning / n;
    state.counters["spheres_per_truth"] = double(found) / double(std::max(1L, truth));
    state.counters["detected_pct"] = 100.0 * double(detected) / double(std::max(1L, truth));
  }
};

using Clock = std::chrono::steady_clock;
double ms(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double, std::milli>(b - a).count(); }

void BM_Tinyline(benchmark::State& state, char cls) {
  const auto& fs = frames(cls);
  std::size_t k = 0;
  FrameTally tally;
  for (auto _ : state) {
    const Frame& f = fs[k++ % fs.size()];
    PipelineParams p;
    p.gravity = f.scenario.gravity_camera;
    const PipelineResult r = TomatoPipeline(p).run(f.scenario.cloud());
    benchmark::DoNotOptimize(r.tomatoes.data());
    tally.hsi += r.times.hsi_ms, tally.branch += r.times.branch_ms, tally.smooth += r.times.smoothing_ms,
        tally.spheres += r.times.spheres_ms, tally.reasoning += r.times.reasoning_ms;
    std::vector<Eigen::Vector3d> c;
    for (const auto& t : r.tomatoes) c.push_back(t.fit.sphere.centre);
    tally.add_detections(f.scenario, c);
  }
  tally.report(state, /*with_reasoning=*/true);
}

void BM_PlainPcl(benchmark::State& state, char cls) {
  using P = pcl::PointXYZRGB;
  const auto& fs = frames(cls);
  std::size_t k = 0;
  FrameTally tally;
  for (auto _ : state) {
    const Frame& f = fs[k++ % fs.size()];
    const auto t0 = Clock::now();
    // HSI filter: PCL's packed hue is int8 over [-180, 180) deg.
    pcl::ConditionAnd<P>::Ptr cond(new pcl::ConditionAnd<P>);
    const double h = 15.0 * 128.0 / 180.0;
    cond->addComparison(pcl::PackedHSIComparison<P>::ConstPtr(new pcl::PackedHSIComparison<P>("h", pcl::ComparisonOps::GE, -h)));
    cond->addComparison(pcl::PackedHSIComparison<P>::ConstPtr(new pcl::PackedHSIComparison<P>("h", pcl::ComparisonOps::LE, h)));
    cond->addComparison(pcl::PackedHSIComparison<P>::ConstPtr(new pcl::PackedHSIComparison<P>("s", pcl::ComparisonOps::GE, 100)));
    cond->addComparison(pcl::PackedHSIComparison<P>::ConstPtr(new pcl::PackedHSIComparison<P>("s", pcl::ComparisonOps::LE, 250)));
    cond->addComparison(pcl::PackedHSIComparison<P>::ConstPtr(new pcl::PackedHSIComparison<P>("i", pcl::ComparisonOps::GE, 25)));
    cond->addComparison(pcl::PackedHSIComparison<P>::ConstPtr(new pcl::PackedHSIComparison<P>("i", pcl::ComparisonOps::LE, 180)));
    pcl::ConditionalRemoval<P> removal;
    removal.setCondition(cond);
    removal.setInputCloud(f.pcl_cloud);
    pcl::PointCloud<P>::Ptr red(new pcl::PointCloud<P>);
    removal.filter(*red);  // drops NaN points too
    const auto t1 = Clock::now();
    // Branch: Euclidean clusters at 6 cm, the one whose centroid is closest.
    pcl::PointCloud<P>::Ptr branch_cloud(new pcl::PointCloud<P>);
    if (!red->empty()) {
      pcl::search::KdTree<P>::Ptr tree(new pcl::search::KdTree<P>);
      tree->setInputCloud(red);
      std::vector<pcl::PointIndices> clusters;
      pcl::EuclideanClusterExtraction<P> ec;
      ec.setClusterTolerance(0.06);
      ec.setMinClusterSize(150);
      ec.setSearchMethod(tree);
      ec.setInputCloud(red);
      ec.extract(clusters);
      double best = 1e9;
      for (const auto& c : clusters) {
        Eigen::Vector3f m = Eigen::Vector3f::Zero();
        for (int i : c.indices) m += (*red)[std::size_t(i)].getVector3fMap();
        m /= float(c.indices.size());
        if (m.norm() < best) {
          best = m.norm();
          pcl::copyPointCloud(*red, c, *branch_cloud);
        }
      }
    }
    const auto t2 = Clock::now();
    // MLS smoothing with normals (PCL's defaults otherwise).
    pcl::PointCloud<pcl::PointXYZRGBNormal>::Ptr smoothed(new pcl::PointCloud<pcl::PointXYZRGBNormal>);
    if (!branch_cloud->empty()) {
      pcl::MovingLeastSquares<P, pcl::PointXYZRGBNormal> mls;
      pcl::search::KdTree<P>::Ptr tree(new pcl::search::KdTree<P>);
      mls.setInputCloud(branch_cloud);
      mls.setSearchMethod(tree);
      mls.setSearchRadius(0.012);
      mls.setComputeNormals(true);
      mls.process(*smoothed);
    }
    const auto t3 = Clock::now();
    // Iterative RANSAC spheres.
    std::vector<Eigen::Vector3d> centres;
    pcl::PointCloud<pcl::PointXYZRGBNormal>::Ptr rest = smoothed;
    for (int round = 0; round < 12 && rest->size() >= 40; ++round) {
      pcl::SACSegmentation<pcl::PointXYZRGBNormal> seg;
      seg.setModelType(pcl::SACMODEL_SPHERE);
      seg.setMethodType(pcl::SAC_RANSAC);
      seg.setDistanceThreshold(0.004);
      seg.setRadiusLimits(0.025, 0.040);
      seg.setInputCloud(rest);
      pcl::PointIndices::Ptr inliers(new pcl::PointIndices);
      pcl::ModelCoefficients coef;
      seg.segment(*inliers, coef);
      if (inliers->indices.size() < 40 || coef.values.size() < 4) break;
      centres.emplace_back(coef.values[0], coef.values[1], coef.values[2]);
      pcl::PointCloud<pcl::PointXYZRGBNormal>::Ptr next(new pcl::PointCloud<pcl::PointXYZRGBNormal>);
      pcl::ExtractIndices<pcl::PointXYZRGBNormal> ex;
      ex.setInputCloud(rest);
      ex.setIndices(inliers);
      ex.setNegative(true);
      ex.filter(*next);
      rest = next;
    }
    const auto t4 = Clock::now();
    benchmark::DoNotOptimize(centres.data());
    tally.hsi += ms(t0, t1), tally.branch += ms(t1, t2), tally.smooth += ms(t2, t3), tally.spheres += ms(t3, t4);
    tally.add_detections(f.scenario, centres);
  }
  tally.report(state, /*with_reasoning=*/false);
}

// The simulated RGB-D camera: one VGA frame of a class C truss (z-buffer,
// depth noise, missing depth at edges, colours), beside the reference of one
// world ray cast per pixel (depth only, no noise or colour).
void BM_RgbdCameraVga(benchmark::State& state) {
  const eval::Scenario& s = frames('C').front().scenario;
  const sim::RgbdCamera camera;
  std::uint64_t k = 0;
  for (auto _ : state) {
    const sim::RgbdFrame f = camera.render(s.world, s.truss.T_world_camera, k++);
    benchmark::DoNotOptimize(f.rgb.data());
  }
  state.counters["frames_per_s"] = benchmark::Counter(double(state.iterations()), benchmark::Counter::kIsRate);
}

void BM_RaycastPerPixelVga(benchmark::State& state) {
  const eval::Scenario& s = frames('C').front().scenario;
  const sim::PinholeIntrinsics in;
  const Eigen::Isometry3d& T = s.truss.T_world_camera;
  for (auto _ : state) {
    double sum = 0;
    for (int v = 0; v < in.height; ++v)
      for (int u = 0; u < in.width; ++u) {
        const auto hit = s.world.raycast(sim::Ray{T.translation(), T.linear() * in.ray(u, v)});
        if (hit) sum += hit->t_m;
      }
    benchmark::DoNotOptimize(sum);
  }
  state.counters["frames_per_s"] = benchmark::Counter(double(state.iterations()), benchmark::Counter::kIsRate);
}

}  // namespace

BENCHMARK(BM_RgbdCameraVga)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK(BM_RaycastPerPixelVga)->Unit(benchmark::kMillisecond)->MinTime(2.0);
BENCHMARK_CAPTURE(BM_Tinyline, class_A, 'A')->Unit(benchmark::kMillisecond)->Iterations(8);
BENCHMARK_CAPTURE(BM_PlainPcl, class_A, 'A')->Unit(benchmark::kMillisecond)->Iterations(8);
BENCHMARK_CAPTURE(BM_Tinyline, class_B, 'B')->Unit(benchmark::kMillisecond)->Iterations(8);
BENCHMARK_CAPTURE(BM_PlainPcl, class_B, 'B')->Unit(benchmark::kMillisecond)->Iterations(8);
BENCHMARK_CAPTURE(BM_Tinyline, class_C, 'C')->Unit(benchmark::kMillisecond)->Iterations(8);
BENCHMARK_CAPTURE(BM_PlainPcl, class_C, 'C')->Unit(benchmark::kMillisecond)->Iterations(8);

BENCHMARK_MAIN();
