// SPDX-License-Identifier: Apache-2.0
// The tomato pipeline per VGA frame beside a PCL chain that does the same
// work with PCL's classes (docs/benchmarks.md, "Tomato reasoning"):
//
//   ConditionalRemoval with PackedHSIComparison (the thesis's HSI ranges)
//   -> EuclideanClusterExtraction at the pipeline's tolerance (8 cm, at least
//   150 points, the closest cluster) -> VoxelGrid at the pipeline's 3 mm ->
//   MovingLeastSquares (1.2 cm, order 2, normals turned to the camera) ->
//   SACSegmentationFromNormals SACMODEL_NORMAL_SPHERE (RANSAC, 4 mm, radius
//   2.5-4 cm, 300 iterations), repeated on the remaining points until fewer
//   than 40 remain or no model of 40 inliers is found.
//
// BM_Tinyline and BM_PclChain run the whole chains and report per-stage
// milliseconds and the detections (a sphere within 1 cm of a true centre);
// the BM_Stage* pairs time one stage each, ours and PCL's, on the very same
// input (what the pipeline handed that stage on the same frame), so the
// ratio per stage compares like with like.
//
//   build/bench/tomato_reasoning/tomato_reasoning_bench
#include <algorithm>
#include <chrono>
#include <vector>

#include <benchmark/benchmark.h>

#include <pcl/ModelCoefficients.h>
#include <pcl/filters/conditional_removal.h>
#include <pcl/filters/extract_indices.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/extract_clusters.h>
#include <pcl/segmentation/sac_segmentation.h>
#include <pcl/surface/mls.h>

#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/pcl_conversions.hpp"
#include "tomato_reasoning/pipeline.hpp"

using namespace tinyline;
using namespace tinyline::tomato_reasoning;

namespace {

struct Frame {
  eval::Scenario scenario;
  pcl::PointCloud<pcl::PointXYZRGB>::Ptr pcl_cloud;
  // What the pipeline handed each stage on this frame (the stage benchmarks' inputs).
  PipelineParams params;
  std::vector<Eigen::Vector3f> red;  ///< HSI-filtered points
  Indices branch;                    ///< the chosen branch, into red
  std::vector<Eigen::Vector3f> thinned;
  SmoothedCloud smoothed;
};

const std::vector<Frame>& frames(char cls) {
  static std::vector<Frame> a, b, c;
  auto& out = cls == 'A' ? a : cls == 'B' ? b : c;
  if (out.empty()) {
    for (std::uint64_t seed = 1; seed <= 8; ++seed) {
      Frame f{eval::make_scenario(*sim::parse_truss_class(std::string(1, cls)), seed), nullptr, {}, {}, {}, {}, {}};
      f.pcl_cloud.reset(new pcl::PointCloud<pcl::PointXYZRGB>(to_pcl(f.scenario.cloud())));
      f.params.gravity = f.scenario.gravity_camera;
      const PipelineResult r = TomatoPipeline(f.params).run(f.scenario.cloud());
      f.red = r.red_xyz;
      if (const Cluster* br = r.branch.branch()) f.branch = br->indices;
      f.thinned = voxel_thin(f.red, f.branch, f.params.smoothing.voxel_m);
      f.smoothed = r.smoothed;
      out.push_back(std::move(f));
    }
  }
  return out;
}

int matched(const eval::Scenario& s, const std::vector<Eigen::Vector3d>& centres) {
  int n = 0;
  for (const auto& t : s.truth)
    n += std::any_of(centres.begin(), centres.end(),
                     [&](const Eigen::Vector3d& c) { return (c - t.centre_m).norm() <= 0.01; });
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

// The whole pipeline; `before`: without the seen pedicel (the pipeline as it
// was before it), for the side-by-side.
void run_tinyline(benchmark::State& state, char cls, bool before) {
  const auto& fs = frames(cls);
  std::size_t k = 0;
  FrameTally tally;
  for (auto _ : state) {
    const Frame& f = fs[k++ % fs.size()];
    PipelineParams p;
    p.gravity = f.scenario.gravity_camera;
    p.pedicel.enabled = !before;
    const PipelineResult r = TomatoPipeline(p).run(f.scenario.cloud());
    benchmark::DoNotOptimize(r.tomatoes.data());
    tally.hsi += r.times.hsi_ms, tally.branch += r.times.branch_ms, tally.smooth += r.times.smoothing_ms,
        tally.spheres += r.times.spheres_ms, tally.reasoning += r.times.reasoning_ms + r.times.green_ms;
    std::vector<Eigen::Vector3d> c;
    for (const auto& t : r.tomatoes) c.push_back(t.fit.sphere.centre);
    tally.add_detections(f.scenario, c);
  }
  tally.report(state, /*with_reasoning=*/true);
}

void BM_Tinyline(benchmark::State& state, char cls) { run_tinyline(state, cls, false); }
void BM_TinylineBefore(benchmark::State& state, char cls) { run_tinyline(state, cls, true); }

// PCL's stages, with the pipeline's parameters.
using P = pcl::PointXYZRGB;
using PN = pcl::PointNormal;

pcl::PointCloud<P>::Ptr pcl_hsi(const pcl::PointCloud<P>::ConstPtr& cloud, const HsiFilterParams& hp) {
  // PCL's packed hue is int8 over [-180, 180) deg.
  pcl::ConditionAnd<P>::Ptr cond(new pcl::ConditionAnd<P>);
  auto add = [&](const char* f, pcl::ComparisonOps::CompareOp op, double v) {
    cond->addComparison(pcl::PackedHSIComparison<P>::ConstPtr(new pcl::PackedHSIComparison<P>(f, op, v)));
  };
  add("h", pcl::ComparisonOps::GE, hp.h_min_deg * 128.0 / 180.0);
  add("h", pcl::ComparisonOps::LE, hp.h_max_deg * 128.0 / 180.0);
  add("s", pcl::ComparisonOps::GE, hp.s_min);
  add("s", pcl::ComparisonOps::LE, hp.s_max);
  add("i", pcl::ComparisonOps::GE, hp.i_min);
  add("i", pcl::ComparisonOps::LE, hp.i_max);
  pcl::ConditionalRemoval<P> removal;
  removal.setCondition(cond);
  removal.setInputCloud(cloud);
  pcl::PointCloud<P>::Ptr red(new pcl::PointCloud<P>);
  removal.filter(*red);  // drops NaN points too
  return red;
}

template <typename PointT>
pcl::PointCloud<PointT> as_pcl(const std::vector<Eigen::Vector3f>& pts, const Indices* indices = nullptr) {
  pcl::PointCloud<PointT> out;
  auto add = [&](const Eigen::Vector3f& q) {
    PointT p;
    p.x = q.x(), p.y = q.y(), p.z = q.z();
    out.push_back(p);
  };
  if (indices) {
    for (int k : *indices) add(pts[std::size_t(k)]);
  } else {
    for (const auto& q : pts) add(q);
  }
  return out;
}

// Euclidean clusters at the branch tolerance; the points of the one whose
// centroid is closest to the camera.
template <typename PointT>
typename pcl::PointCloud<PointT>::Ptr pcl_branch(const typename pcl::PointCloud<PointT>::Ptr& red,
                                                 const BranchClusteringParams& bp) {
  typename pcl::PointCloud<PointT>::Ptr branch(new pcl::PointCloud<PointT>);
  if (red->empty()) return branch;
  typename pcl::search::KdTree<PointT>::Ptr tree(new pcl::search::KdTree<PointT>);
  tree->setInputCloud(red);
  std::vector<pcl::PointIndices> clusters;
  pcl::EuclideanClusterExtraction<PointT> ec;
  ec.setClusterTolerance(bp.tolerance_m);
  ec.setMinClusterSize(bp.min_points);
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
      pcl::copyPointCloud(*red, c, *branch);
    }
  }
  return branch;
}

template <typename PointT>
typename pcl::PointCloud<PointT>::Ptr pcl_thin(const typename pcl::PointCloud<PointT>::ConstPtr& in, double voxel_m) {
  typename pcl::PointCloud<PointT>::Ptr out(new pcl::PointCloud<PointT>);
  pcl::VoxelGrid<PointT> vg;
  const float leaf = float(voxel_m);
  vg.setLeafSize(leaf, leaf, leaf);
  vg.setInputCloud(in);
  vg.filter(*out);
  return out;
}

// MLS with normals, turned to the camera at the origin as the pipeline's are.
template <typename PointT>
pcl::PointCloud<PN>::Ptr pcl_mls(const typename pcl::PointCloud<PointT>::Ptr& in, const SmoothingParams& sp) {
  pcl::PointCloud<PN>::Ptr out(new pcl::PointCloud<PN>);
  if (in->empty()) return out;
  pcl::MovingLeastSquares<PointT, PN> mls;
  typename pcl::search::KdTree<PointT>::Ptr tree(new pcl::search::KdTree<PointT>);
  mls.setInputCloud(in);
  mls.setSearchMethod(tree);
  mls.setSearchRadius(sp.search_radius_m);
  mls.setPolynomialOrder(sp.polynomial_order);
  mls.setComputeNormals(true);
  mls.process(*out);
  for (auto& p : out->points)
    if (p.getVector3fMap().dot(p.getNormalVector3fMap()) > 0) p.getNormalVector3fMap() *= -1.0f;
  return out;
}

// Iterative SACSegmentationFromNormals with SACMODEL_NORMAL_SPHERE.
std::vector<Eigen::Vector3d> pcl_spheres(pcl::PointCloud<PN>::Ptr rest, const SphereRansacParams& sp) {
  std::vector<Eigen::Vector3d> centres;
  for (int round = 0; round < sp.max_spheres && int(rest->size()) >= sp.min_remaining; ++round) {
    pcl::SACSegmentationFromNormals<PN, PN> seg;
    seg.setModelType(pcl::SACMODEL_NORMAL_SPHERE);
    seg.setMethodType(pcl::SAC_RANSAC);
    seg.setDistanceThreshold(sp.inlier_distance_m);
    // Angle [rad] against distance [m]: a normal 35 deg off costs about 3 mm.
    seg.setNormalDistanceWeight(0.005);
    seg.setRadiusLimits(sp.radius_min_m, sp.radius_max_m);
    seg.setMaxIterations(sp.max_iterations);
    seg.setProbability(sp.confidence);
    seg.setInputCloud(rest);
    seg.setInputNormals(rest);
    pcl::PointIndices::Ptr inliers(new pcl::PointIndices);
    pcl::ModelCoefficients coef;
    seg.segment(*inliers, coef);
    if (int(inliers->indices.size()) < sp.min_inliers || coef.values.size() < 4) break;
    centres.emplace_back(coef.values[0], coef.values[1], coef.values[2]);
    pcl::PointCloud<PN>::Ptr next(new pcl::PointCloud<PN>);
    pcl::ExtractIndices<PN> ex;
    ex.setInputCloud(rest);
    ex.setIndices(inliers);
    ex.setNegative(true);
    ex.filter(*next);
    rest = next;
  }
  return centres;
}

void BM_PclChain(benchmark::State& state, char cls) {
  const auto& fs = frames(cls);
  std::size_t k = 0;
  FrameTally tally;
  double thin_ms = 0;
  for (auto _ : state) {
    const Frame& f = fs[k++ % fs.size()];
    const PipelineParams& pp = f.params;
    const auto t0 = Clock::now();
    const pcl::PointCloud<P>::Ptr red = pcl_hsi(f.pcl_cloud, pp.hsi);
    const auto t1 = Clock::now();
    const pcl::PointCloud<P>::Ptr branch = pcl_branch<P>(red, pp.branch);
    const auto t2 = Clock::now();
    const pcl::PointCloud<P>::Ptr thinned = pcl_thin<P>(branch, pp.smoothing.voxel_m);
    const auto t3 = Clock::now();
    const pcl::PointCloud<PN>::Ptr smoothed = pcl_mls<P>(thinned, pp.smoothing);
    const auto t4 = Clock::now();
    const std::vector<Eigen::Vector3d> centres = pcl_spheres(smoothed, pp.spheres);
    const auto t5 = Clock::now();
    benchmark::DoNotOptimize(centres.data());
    thin_ms += ms(t2, t3);
    tally.hsi += ms(t0, t1), tally.branch += ms(t1, t2), tally.smooth += ms(t2, t4), tally.spheres += ms(t4, t5);
    tally.add_detections(f.scenario, centres);
  }
  tally.report(state, /*with_reasoning=*/false);
  state.counters["thinning_ms"] = thin_ms / double(std::max<long>(1, tally.frames));
}

// One stage on the same input, ours (`pcl` false) or PCL's.
void BM_StageHsi(benchmark::State& state, bool pcl) {
  const auto& fs = frames('B');
  std::size_t k = 0;
  for (auto _ : state) {
    const Frame& f = fs[k++ % fs.size()];
    if (pcl) {
      benchmark::DoNotOptimize(pcl_hsi(f.pcl_cloud, f.params.hsi)->size());
    } else {
      benchmark::DoNotOptimize(filter_hsi(view_of(*f.pcl_cloud), f.params.hsi).indices.size());
    }
  }
}

void BM_StageBranch(benchmark::State& state, bool pcl) {
  const auto& fs = frames('B');
  std::size_t k = 0;
  for (auto _ : state) {
    const Frame& f = fs[k++ % fs.size()];
    if (pcl) {
      state.PauseTiming();
      pcl::PointCloud<pcl::PointXYZ>::Ptr red(new pcl::PointCloud<pcl::PointXYZ>(as_pcl<pcl::PointXYZ>(f.red)));
      state.ResumeTiming();
      benchmark::DoNotOptimize(pcl_branch<pcl::PointXYZ>(red, f.params.branch)->size());
    } else {
      state.PauseTiming();
      ColorCloud red;
      for (const auto& q : f.red) red.push_back(q, Rgb{0, 0, 0});
      Indices all(red.size());
      for (std::size_t i = 0; i < all.size(); ++i) all[i] = int(i);
      state.ResumeTiming();
      benchmark::DoNotOptimize(cluster_branches(red, all, f.params.branch).chosen);
    }
  }
}

void BM_StageThinning(benchmark::State& state, bool pcl) {
  const auto& fs = frames('B');
  std::size_t k = 0;
  for (auto _ : state) {
    const Frame& f = fs[k++ % fs.size()];
    if (pcl) {
      state.PauseTiming();
      pcl::PointCloud<pcl::PointXYZ>::Ptr branch(
          new pcl::PointCloud<pcl::PointXYZ>(as_pcl<pcl::PointXYZ>(f.red, &f.branch)));
      state.ResumeTiming();
      benchmark::DoNotOptimize(pcl_thin<pcl::PointXYZ>(branch, f.params.smoothing.voxel_m)->size());
    } else {
      benchmark::DoNotOptimize(voxel_thin(f.red, f.branch, f.params.smoothing.voxel_m).size());
    }
  }
}

void BM_StageMls(benchmark::State& state, bool pcl) {
  const auto& fs = frames('B');
  std::size_t k = 0;
  for (auto _ : state) {
    const Frame& f = fs[k++ % fs.size()];
    if (pcl) {
      state.PauseTiming();
      pcl::PointCloud<pcl::PointXYZ>::Ptr in(new pcl::PointCloud<pcl::PointXYZ>(as_pcl<pcl::PointXYZ>(f.thinned)));
      state.ResumeTiming();
      benchmark::DoNotOptimize(pcl_mls<pcl::PointXYZ>(in, f.params.smoothing)->size());
    } else {
      state.PauseTiming();
      Indices all(f.thinned.size());
      for (std::size_t i = 0; i < all.size(); ++i) all[i] = int(i);
      SmoothingParams sp = f.params.smoothing;
      sp.voxel_m = 0;  // already thinned
      state.ResumeTiming();
      benchmark::DoNotOptimize(smooth_mls(f.thinned, all, sp).points.size());
    }
  }
}

void BM_StageSpheres(benchmark::State& state, bool pcl) {
  const auto& fs = frames('B');
  std::size_t k = 0;
  FrameTally tally;
  for (auto _ : state) {
    const Frame& f = fs[k++ % fs.size()];
    std::vector<Eigen::Vector3d> centres;
    if (pcl) {
      state.PauseTiming();
      pcl::PointCloud<PN>::Ptr in(new pcl::PointCloud<PN>);
      for (std::size_t i = 0; i < f.smoothed.size(); ++i) {
        PN p;
        p.getVector3fMap() = f.smoothed.points[i];
        p.getNormalVector3fMap() = f.smoothed.normals[i];
        in->push_back(p);
      }
      state.ResumeTiming();
      centres = pcl_spheres(in, f.params.spheres);
    } else {
      for (const auto& s : segment_spheres(f.smoothed.points, f.smoothed.normals, f.params.spheres).spheres)
        centres.push_back(s.sphere.centre);
    }
    state.PauseTiming();
    tally.add_detections(f.scenario, centres);
    state.ResumeTiming();
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
BENCHMARK_CAPTURE(BM_TinylineBefore, class_A, 'A')->Unit(benchmark::kMillisecond)->Iterations(8);
BENCHMARK_CAPTURE(BM_TinylineBefore, class_B, 'B')->Unit(benchmark::kMillisecond)->Iterations(8);
BENCHMARK_CAPTURE(BM_TinylineBefore, class_C, 'C')->Unit(benchmark::kMillisecond)->Iterations(8);
BENCHMARK_CAPTURE(BM_PclChain, class_A, 'A')->Unit(benchmark::kMillisecond)->Iterations(8);
BENCHMARK_CAPTURE(BM_Tinyline, class_B, 'B')->Unit(benchmark::kMillisecond)->Iterations(8);
BENCHMARK_CAPTURE(BM_PclChain, class_B, 'B')->Unit(benchmark::kMillisecond)->Iterations(8);
BENCHMARK_CAPTURE(BM_Tinyline, class_C, 'C')->Unit(benchmark::kMillisecond)->Iterations(8);
BENCHMARK_CAPTURE(BM_PclChain, class_C, 'C')->Unit(benchmark::kMillisecond)->Iterations(8);
// Stage by stage on class B's 8 frames (each iteration one frame), ours then PCL's.
BENCHMARK_CAPTURE(BM_StageHsi, tinyline, false)->Unit(benchmark::kMillisecond)->Iterations(40);
BENCHMARK_CAPTURE(BM_StageHsi, pcl, true)->Unit(benchmark::kMillisecond)->Iterations(40);
BENCHMARK_CAPTURE(BM_StageBranch, tinyline, false)->Unit(benchmark::kMillisecond)->Iterations(40);
BENCHMARK_CAPTURE(BM_StageBranch, pcl, true)->Unit(benchmark::kMillisecond)->Iterations(8);
BENCHMARK_CAPTURE(BM_StageThinning, tinyline, false)->Unit(benchmark::kMillisecond)->Iterations(40);
BENCHMARK_CAPTURE(BM_StageThinning, pcl, true)->Unit(benchmark::kMillisecond)->Iterations(40);
BENCHMARK_CAPTURE(BM_StageMls, tinyline, false)->Unit(benchmark::kMillisecond)->Iterations(40);
BENCHMARK_CAPTURE(BM_StageMls, pcl, true)->Unit(benchmark::kMillisecond)->Iterations(40);
BENCHMARK_CAPTURE(BM_StageSpheres, tinyline, false)->Unit(benchmark::kMillisecond)->Iterations(40);
BENCHMARK_CAPTURE(BM_StageSpheres, pcl, true)->Unit(benchmark::kMillisecond)->Iterations(40);

BENCHMARK_MAIN();
