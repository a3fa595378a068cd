// SPDX-License-Identifier: Apache-2.0
// Discretised elastic rods with rigid fruit and frictional contacts: the
// second physics of the truss generator (TrussParams::physics =
// kElasticRod), deliberately not the pendulum-and-frictionless-contact model
// that the reasoning of thesis 4.3.3 inverts.
//
// A network of nodes (3 degrees of freedom each) joined by
//   - segments: axial springs, stiffness E A / L0;
//   - hinges between two segments: bending, energy k/2 |u2 - u1 - rest|^2
//     with u the unit segment directions and k = E I / l (the discrete form
//     of the beam's E I / 2 kappa^2 ds; the rest turn is kept in the world
//     frame, exact for straight rods and right to first order in the
//     rotation for the slightly curved peduncle);
//   - ties: a node held at an offset from a point between two nodes (a
//     pedicel's knuckle on the peduncle);
//   - bodies: a fruit is a node at its centre welded to its pedicel's last
//     node (a stiff segment and a stiff hinge), with its mass and the
//     bounding radius that contacts see;
//   - tubes: the segments that fruit can touch (pedicels and peduncle).
// Contacts are penalties (normal force k_c times the overlap) with Coulomb
// friction (Cundall-Strack: a tangential spring per contact that slips when
// it would exceed mu times the normal force). Contact forces act at the
// fruit centres (the moment friction would put on a fruit is left out).
//
// The rest state is found by a damped dynamic settle (FIRE, Bitzek et al.
// 2006) in mass-scaled coordinates: fictitious nodal masses from a
// Gershgorin bound of the stiffness, so that a unit step is stable.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

namespace tinyline::sim::rod {

struct Segment {
  int a = 0, b = 0;
  double rest_m = 0.0;
  double axial_n = 0.0;  ///< E A [N]
};

/// Bending between segment (a1 -> b1) and segment (a2 -> b2).
struct Hinge {
  int a1 = 0, b1 = 0, a2 = 0, b2 = 0;
  double k_nm = 0.0;                               ///< E I / l [N m]
  Eigen::Vector3d rest = Eigen::Vector3d::Zero();  ///< u2 - u1 at rest
};

/// Node q held at (1 - w) x_a + w x_b + offset by a spring of stiffness k.
struct Tie {
  int q = 0, a = 0, b = 0;
  double w = 0.0;
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
  double k_n_m = 0.0;
};

struct Body {
  int node = 0;  ///< the fruit's centre
  int rod = -2;  ///< its own pedicel's rod id, never touched by it (-2: none; -1 is the peduncle)
  double radius_m = 0.0;
  double mass_kg = 0.0;
};

/// A segment fruit can touch; `rod` groups the segments of one pedicel (or
/// the peduncle, rod -1) so that a fruit keeps one contact per rod.
struct Tube {
  int a = 0, b = 0;
  int rod = -1;
  double radius_m = 0.0;
};

struct Network {
  std::vector<Eigen::Vector3d> x;
  std::vector<char> fixed;
  std::vector<double> lumped_mass_kg;  ///< rod mass at each node (gravity only)
  std::vector<Segment> segments;
  std::vector<Hinge> hinges;
  std::vector<Tie> ties;
  std::vector<Body> bodies;
  std::vector<Tube> tubes;

  int add_node(const Eigen::Vector3d& p, bool is_fixed = false);
  /// A segment from a to b whose current length is its rest length.
  void add_segment(int a, int b, double axial_n);
  /// A hinge whose current turn is its rest turn.
  void add_hinge(int a1, int b1, int a2, int b2, double k_nm);
};

struct SettleOptions {
  double gravity_m_s2 = 9.81;
  double contact_stiffness_n_m = 5e4;
  double friction = 0.5;      ///< Coulomb coefficient
  double tolerance_n = 1e-5;  ///< converged when no free node feels more [N]
  int max_iterations = 400000;
};

enum class ContactWith : int { kBody = 0, kTube = 1 };

struct Contact {
  int body = -1;  ///< index into bodies
  ContactWith with = ContactWith::kBody;
  int other = -1;  ///< the other body, or the touched tube's rod
  double normal_n = 0.0;
  double tangential_n = 0.0;
  Eigen::Vector3d force_on_body = Eigen::Vector3d::Zero();  ///< normal + friction [N]
  double penetration_m = 0.0;
};

struct SettleReport {
  bool converged = false;
  int iterations = 0;
  double max_residual_n = 0.0;  ///< largest net force on a free node at the end [N]
  double max_penetration_m = 0.0;
  std::vector<Contact> contacts;  ///< at rest
};

/// Moves the network's free nodes to a rest state under gravity, elasticity
/// and contacts.
SettleReport settle(Network& net, const SettleOptions& options = {});

/// Second moment of area of a round section [m^4].
[[nodiscard]] double round_section_inertia(double radius_m);

}  // namespace tinyline::sim::rod
