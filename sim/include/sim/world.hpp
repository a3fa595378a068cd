// SPDX-License-Identifier: Apache-2.0
// The simulated world: primitives with poses and materials, and ray casting.
//
// Shapes are defined in their own frame and placed with T_world_object:
//   Plane     z = 0, normal +z; finite rectangle size_m (x, y) or infinite
//   Box       centred, edge lengths size_m (x, y, z)
//   Sphere    centred, radius_m
//   Cylinder  axis z, centred, radius_m, length_m, flat caps
//   Rod       thin cylinder from p0 to p1 (object frame), radius_m, flat caps
//   Mesh      triangles (object frame), both faces
// Surfaces are two-sided: a hit's normal faces the ray.
#pragma once

#include <cstdint>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <variant>
#include <vector>

#include <Eigen/Geometry>

#include <sim/material.hpp>

#include <tinyline/common/status.hpp>

namespace tinyline::sim {

using ObjectId = std::int32_t;
inline constexpr ObjectId kNoObject = -1;
inline constexpr double kInf = std::numeric_limits<double>::infinity();

struct Ray {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d dir = Eigen::Vector3d::UnitZ();  ///< unit length
};

struct PlaneShape {
  Eigen::Vector2d size_m{kInf, kInf};  ///< extent along x and y; infinite by default
};
struct BoxShape {
  Eigen::Vector3d size_m{1, 1, 1};
};
struct SphereShape {
  double radius_m = 0.05;
};
struct CylinderShape {
  double radius_m = 0.05;
  double length_m = 0.1;
};
struct RodShape {
  Eigen::Vector3d p0 = Eigen::Vector3d::Zero();
  Eigen::Vector3d p1 = Eigen::Vector3d::UnitZ();
  double radius_m = 0.003;
};
struct MeshShape {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> triangles;  ///< indices into vertices
};
using Shape = std::variant<PlaneShape, BoxShape, SphereShape, CylinderShape, RodShape, MeshShape>;

/// "plane", "box", ... for messages and errors.
[[nodiscard]] const char* shape_name(const Shape& s);

struct Object {
  std::string name;
  Shape shape;
  Eigen::Isometry3d T_world_object = Eigen::Isometry3d::Identity();
  MaterialId material = kNoMaterial;
};

struct Hit {
  double t_m = kInf;                                  ///< distance along the ray
  Eigen::Vector3d point = Eigen::Vector3d::Zero();    ///< world
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< world, unit, facing the ray origin
  ObjectId object = kNoObject;
  MaterialId material = kNoMaterial;
};

/// Why a shape is not valid (InvalidArgument); ok when it is.
common::Status validate_shape(const Shape& s);

class World {
 public:
  World() : materials_(MaterialLibrary::builtin()) {}
  explicit World(MaterialLibrary materials) : materials_(std::move(materials)) {}

  /// Adds an object; throws std::invalid_argument naming the object when its
  /// shape is degenerate (non-positive size, NaN) or its material unknown.
  ObjectId add(Object o);
  /// Moves an object (links of a moving robot, a swinging tomato).
  void set_pose(ObjectId id, const Eigen::Isometry3d& T_world_object);

  [[nodiscard]] const Object& object(ObjectId id) const { return objects_.at(static_cast<std::size_t>(id)).obj; }
  [[nodiscard]] std::size_t size() const { return objects_.size(); }
  [[nodiscard]] std::optional<ObjectId> find(std::string_view name) const;

  MaterialLibrary& materials() { return materials_; }
  [[nodiscard]] const MaterialLibrary& materials() const { return materials_; }
  [[nodiscard]] const Material& material_of(const Hit& h) const { return materials_.get(h.material); }

  /// Nearest hit with t in (t_min, t_max), or nullopt.
  [[nodiscard]] std::optional<Hit> raycast(const Ray& ray, double t_min = 1e-9, double t_max = kInf) const;
  /// True when anything lies strictly between a and b (shadow rays).
  [[nodiscard]] bool occluded(const Eigen::Vector3d& a, const Eigen::Vector3d& b) const;
  /// Objects whose solid interior contains p (planes and meshes have none).
  [[nodiscard]] std::vector<ObjectId> containing(const Eigen::Vector3d& p) const;

 private:
  struct Entry {
    Object obj;
    Eigen::Isometry3d T_object_world;
    Eigen::Vector3d centre_w;  // bounding sphere in world
    double radius = kInf;      // kInf: unbounded (infinite plane)
    // Rods are cylinders in a frame along p0->p1:
    Eigen::Isometry3d T_world_local;
    Eigen::Isometry3d T_local_world;
    double half_len = 0.0;
    Eigen::AlignedBox3d mesh_box;
  };
  void refresh(Entry& e);
  bool intersect(const Entry& e, const Ray& ray, double t_min, double t_max, Hit& hit) const;

  MaterialLibrary materials_;
  std::vector<Entry> objects_;
};

}  // namespace tinyline::sim
