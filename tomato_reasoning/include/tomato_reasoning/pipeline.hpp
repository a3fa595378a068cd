// SPDX-License-Identifier: Apache-2.0
// The whole vision pipeline of thesis Figure 4.4 on one RGB-D frame:
// HSI filter -> branch clustering -> smoothing -> sphere segmentation ->
// contact graph, pedicel distributions, pick order, cut plans. Every stage is
// usable on its own (see the stage headers); this runs them in order with
// one parameter struct, times each stage, and says where and why it stopped
// when it produces nothing.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Geometry>

#include "tomato_reasoning/branch_clustering.hpp"
#include "tomato_reasoning/cloud.hpp"
#include "tomato_reasoning/hsi_filter.hpp"
#include "tomato_reasoning/pedicel_evidence.hpp"
#include "tomato_reasoning/reasoning.hpp"
#include "tomato_reasoning/smoothing.hpp"
#include "tomato_reasoning/sphere_ransac.hpp"

#include <tinyline/common/status.hpp>

namespace tinyline::tomato_reasoning {

struct PipelineParams {
  HsiFilterParams hsi;
  BranchClusteringParams branch;
  SmoothingParams smoothing;
  SphereRansacParams spheres;
  NoiseBiasParams noise_bias;  ///< the spheres' bias under depth noise, removed after the segmentation
  ForceModelParams force;
  PickOrderParams pick;
  CutParams cut;
  PedicelEvidenceParams pedicel;  ///< the seen calyx and pedicel (posterior over the force model's prior)
  /// Unit direction of gravity in the cloud's frame (a level camera's
  /// optical frame: +y). Normalised on use.
  Eigen::Vector3d gravity{0, 1, 0};
};

common::Status validate(const PipelineParams& p);

struct StageTimes {
  double hsi_ms = 0, branch_ms = 0, smoothing_ms = 0, spheres_ms = 0, reasoning_ms = 0;
  double green_ms = 0;  ///< gathering the green points for the pedicel evidence
  [[nodiscard]] double total_ms() const {
    return hsi_ms + branch_ms + smoothing_ms + spheres_ms + reasoning_ms + green_ms;
  }
};

struct Tomato {
  SphereFit fit;
  /// The pedicel direction the pick uses: the posterior when the camera saw
  /// the pedicel or calyx (`sighting.seen`), else the force model's.
  PedicelEstimate pedicel;
  PedicelEstimate pedicel_prior;  ///< the force model's alone (Eq. 4.18-4.22)
  PedicelSighting sighting;       ///< what the camera saw of the pedicel
  /// Planned on `pedicel`; its point lies on the seen pedicel when
  /// `sighting.cut_point_seen` and the plan's direction agrees with it.
  CutPlan cut;
  PickCost cost;
  int pick_rank = -1;  ///< 0 = pick first
};

/// One camera view for a multi-view run: its cloud (in the camera's frame;
/// a ColorCloud or a view of a PCL cloud, borrowed) and the camera's pose in
/// the reference frame the results are given in.
struct View {
  CloudView cloud;
  Eigen::Isometry3d T_ref_camera = Eigen::Isometry3d::Identity();
};

/// Where a pipeline run stopped.
enum class PipelineStage { kNone, kInput, kHsi, kBranch, kSmoothing, kSpheres };
/// "input", "hsi", "branch", "smoothing", "spheres"; "" for kNone (it did not stop).
[[nodiscard]] std::string_view to_string(PipelineStage stage);

struct PipelineResult {
  /// InvalidArgument: bad input (stage kInput); NotFound: nothing found at
  /// `stage`. A result never run is NotFound at kNone.
  common::Status status{common::StatusCode::NotFound, ""};
  PipelineStage stage = PipelineStage::kNone;  ///< where it stopped; kNone when ok
  std::size_t finite_points = 0;
  std::size_t red_points = 0;
  /// The HSI-filtered points of every view in the reference frame (what the
  /// branch clusters' indices refer to), and the view each came from.
  std::vector<Eigen::Vector3f> red_xyz;
  std::vector<std::uint8_t> red_view;
  std::vector<Eigen::Vector3f> viewpoints;  ///< camera origins in the reference frame
  /// Green points (calyx, pedicel, stem, leaf colours) near the fruit found,
  /// reference frame: the pedicel evidence's input.
  GreenPoints green;
  BranchResult branch;
  SmoothedCloud smoothed;
  SphereSegmentation segmentation;
  std::vector<ContactEdge> edges;
  std::vector<Tomato> tomatoes;  ///< in segmentation order
  std::vector<int> pick_order;   ///< indices into tomatoes, first to pick first
  StageTimes times;
};

class TomatoPipeline {
 public:
  /// Throws std::invalid_argument with the reason on bad parameters.
  explicit TomatoPipeline(PipelineParams params = {});
  [[nodiscard]] const PipelineParams& params() const { return params_; }

  /// One view; the camera is at the origin of the cloud's frame, which is
  /// the reference frame. Takes a ColorCloud, or a PCL cloud through
  /// `view_of` (pcl_conversions.hpp) without copying it.
  [[nodiscard]] PipelineResult run(const CloudView& cloud) const;
  /// Several views of one branch (thesis 4.5: two hand-camera views), merged
  /// in the reference frame (`gravity` is given in that frame). At most 255 views.
  [[nodiscard]] PipelineResult run(const std::vector<View>& views) const;
  /// From spheres onwards (the reasoning of 4.3.3 alone), for spheres found
  /// elsewhere.
  [[nodiscard]] PipelineResult reason_about(const std::vector<SphereFit>& spheres) const;

 private:
  void reason(PipelineResult& r) const;
  PipelineParams params_;
};

}  // namespace tinyline::tomato_reasoning
