// SPDX-License-Identifier: Apache-2.0
// Physical and geometric reasoning (thesis 4.3.3): from the spheres of one
// branch to a contact graph, the distribution of each tomato's pedicel
// direction, the order to pick them in and where to cut.
//
//   Contact graph (Eq. 4.17): spheres i, j touch when
//     | |c_i - c_j| - (r_i + r_j) | <= d_e.
//   Force model (Eq. 4.18-4.22): a neighbour j pushes tomato i along the line
//   of centres, from c_j towards c_i (a contact can only push; Newton's third
//   law makes F_ij = -F_ji, so one magnitude per edge), with magnitude
//   eps * theta * r_e, eps ~ N(0.3, 0.25) truncated to [0, 1) (Eq. 4.19-4.20),
//   r_e the mean radius of the two; gravity on i is theta * r_i along g
//   (weight_exponent 1, the thesis; 3 makes it the fruit's volume). The
//   pedicel balances them: F_ip = -(G_i + sum_j F_ij) (Eq. 4.22), and its
//   direction is the pedicel direction.
//   Distribution: sampled (eps per edge), each sample spread by a
//   von Mises-Fisher kernel of concentration `kernel_kappa` (what the model
//   leaves out: stiff pedicels, fruit that are not spheres, missed
//   neighbours). kappa = 0 is the thesis's model as written, whose
//   distribution is degenerate (a point for a lone tomato, an arc for one
//   edge); the default is fitted on held-out trusses (docs/tomato_reasoning.md).
//   Pick order (Eq. 4.23): C_i = sigma . [-Ep_i, N_i, angle(F^e_ip, -G_i)],
//   lowest first.
//   Cut direction (Eq. 4.24): the direction u whose cone of half angle
//   atan(opening / 2 / (r + cut_offset)) holds the most pedicel probability,
//   with the cut point outside every tomato.
//
// Frames: whatever frame the spheres are in; `gravity` is the unit direction
// of gravity in that frame (for a camera looking level, optical +y).
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "tomato_reasoning/sphere_ransac.hpp"

#include <tinyline/common/status.hpp>

namespace tinyline::tomato_reasoning {

struct ContactEdge {
  int i = -1, j = -1;  ///< sphere indices, i < j
  double gap_m = 0.0;  ///< |c_i - c_j| - (r_i + r_j) [m]
};

/// Eq. 4.17 with tolerance d_e [m].
[[nodiscard]] std::vector<ContactEdge> contact_graph(const std::vector<Sphere>& spheres, double d_e_m);

struct ForceModelParams {
  double contact_tolerance_m = 0.012;  ///< Eq. 4.17 d_e [m]
  double eps_mean = 0.3;               ///< Eq. 4.19 mu
  double eps_variance = 0.25;          ///< Eq. 4.19 sigma^2
  double eps_max = 1.0;                ///< truncation [0, eps_max)
  double weight_exponent = 1.0;        ///< gravity ~ r^exponent (thesis: theta * r)
  /// vMF concentration of the kernel (0: the thesis's model, far too sure of
  /// itself). Fitted so that the truth lies in the HPD50 region half the time:
  /// `tomato_eval --classes A,B,C --seeds 201-250 --views 2 --fit-kappa`
  /// (fitting trusses, two views; docs/tomato_reasoning.md).
  double kernel_kappa = 152.0;
  int samples = 400;  ///< Monte Carlo draws per tomato
  std::uint64_t seed = 1;
};

common::Status validate(const ForceModelParams& p);

/// The distribution of one tomato's pedicel direction.
class PedicelDistribution {
 public:
  PedicelDistribution() = default;
  PedicelDistribution(std::vector<Eigen::Vector3d> draws, double kappa, std::uint64_t seed);

  /// Unit directions of the force model's draws (kernel centres).
  [[nodiscard]] const std::vector<Eigen::Vector3d>& draws() const { return draws_; }
  [[nodiscard]] double kappa() const { return kappa_; }
  /// Probability density on the unit sphere [1/sr] at unit direction d. With
  /// kappa = 0 the draws are binned on cells of `cell_deg` (so that a
  /// degenerate distribution still has a density to compare).
  [[nodiscard]] double density(const Eigen::Vector3d& d, double cell_deg = 5.0) const;
  /// Directions drawn from the full distribution (draw + kernel), reproducible.
  [[nodiscard]] std::vector<Eigen::Vector3d> sample(int n, std::uint64_t seed) const;
  /// The density level above which `mass` of the probability lies (HPD
  /// region), estimated from `n` draws of the distribution.
  [[nodiscard]] double hpd_level(double mass, int n = 400, double cell_deg = 5.0) const;
  /// Is unit direction d inside the most probable `mass` of the distribution?
  [[nodiscard]] bool in_hpd(const Eigen::Vector3d& d, double mass, int n = 400, double cell_deg = 5.0) const;
  /// Density on a (phi, theta) grid, phi in [-pi, pi) along columns, theta in
  /// [0, pi] from +z along rows (Figure 4.5), in the frame of the draws.
  [[nodiscard]] std::vector<std::vector<double>> grid(int n_phi, int n_theta, double cell_deg = 5.0) const;
  /// The same distribution in another frame (d' = R d), e.g. gravity-aligned for plots.
  [[nodiscard]] PedicelDistribution rotated(const Eigen::Matrix3d& R) const;

 private:
  std::vector<Eigen::Vector3d> draws_;
  double kappa_ = 0.0;
  std::uint64_t seed_ = 1;
};

struct PedicelEstimate {
  int sphere = -1;
  int edges = 0;                                             ///< N of Eq. 4.23
  Eigen::Vector3d expected_force = Eigen::Vector3d::Zero();  ///< E[F_ip] in units of theta [m of radius]
  Eigen::Vector3d expected_dir = Eigen::Vector3d::UnitZ();   ///< unit F^e_ip
  double spread50_deg = 0.0;                                 ///< median angle of the distribution from expected_dir
  double spread90_deg = 0.0;                                 ///< 90th percentile angle
  double gravity_angle_rad = 0.0;                            ///< angle(F^e_ip, -G_i) of Eq. 4.23
  PedicelDistribution distribution;
};

/// The median and 90th-percentile angle [deg] of `n` draws of `d` from the
/// unit direction `centre` (reproducible for a seed).
[[nodiscard]] std::pair<double, double> spread_deg(const PedicelDistribution& d, const Eigen::Vector3d& centre, int n,
                                                   std::uint64_t seed);

/// Eq. 4.18-4.22 for every sphere of a branch.
[[nodiscard]] std::vector<PedicelEstimate> estimate_pedicels(const std::vector<Sphere>& spheres,
                                                             const std::vector<ContactEdge>& edges,
                                                             const Eigen::Vector3d& gravity,
                                                             const ForceModelParams& params = {});

struct PickOrderParams {
  double w_energy_per_m = 10.0;  ///< sigma_1: per metre of height, times r / 3 cm (the thesis's weight theta r)
  double w_edges = 0.5;          ///< sigma_2: per contact edge
  double w_angle_per_rad = 1.0;  ///< sigma_3: per radian between the pedicel and straight up
  /// N counts a contact by how surely it is one: fully at a gap below d_e -
  /// this, not at all above d_e + this, linearly between [m]; a gap near
  /// d_e then no longer flips the order between frames. 0: Eq. 4.23's count.
  double edge_softness_m = 0.004;
};

struct PickCost {
  int sphere = -1;
  double cost = 0.0;
  double energy_term = 0.0, edge_term = 0.0, angle_term = 0.0;  ///< the three parts of Eq. 4.23, weighted
};

/// Eq. 4.23: every sphere's cost, cheapest (first to pick) first; contacts
/// within `contact_tolerance_m` (Eq. 4.17 d_e) are N's.
[[nodiscard]] std::vector<PickCost> pick_order(const std::vector<Sphere>& spheres,
                                               const std::vector<PedicelEstimate>& pedicels,
                                               const Eigen::Vector3d& gravity, const PickOrderParams& params = {},
                                               double contact_tolerance_m = ForceModelParams{}.contact_tolerance_m);

struct CutParams {
  double scissor_opening_m = 0.02;  ///< the thesis's scissors
  /// Cut this far beyond the fruit's surface along the pedicel [m]: close
  /// to the calyx, where the pedicel surely is (pedicels are 1-4 cm long).
  double cut_offset_m = 0.008;
  int candidates = 200;  ///< directions tried (draws of the distribution)
};

struct CutPlan {
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();  ///< unit, from the centre towards the cut
  Eigen::Vector3d point = Eigen::Vector3d::Zero();       ///< where the blades should meet [m]
  double half_angle_rad = 0.0;                           ///< the blades' angular cover seen from the centre
  double coverage = 0.0;                                 ///< pedicel probability inside that cover
  double expected_coverage = 0.0;                        ///< ... for a cut along the expectation, for comparison
  bool blocked = false;                                  ///< every candidate's cut point lies inside another tomato
};

/// Eq. 4.24 for sphere `index`.
[[nodiscard]] CutPlan plan_cut(const std::vector<Sphere>& spheres, int index, const PedicelEstimate& pedicel,
                               const CutParams& params = {});

/// Mean of eps ~ N(mu, var) truncated to [0, max) (what E[F_ip] uses).
[[nodiscard]] double truncated_normal_mean(double mu, double var, double max);

}  // namespace tinyline::tomato_reasoning
