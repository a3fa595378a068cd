// SPDX-License-Identifier: Apache-2.0
#include <sim/world.hpp>

#include <cmath>
#include <stdexcept>

namespace tinyline::sim {

namespace {

constexpr double kEps = 1e-12;

template <class... Ts>
struct Overloaded : Ts... {
  using Ts::operator()...;
};
template <class... Ts>
Overloaded(Ts...) -> Overloaded<Ts...>;

bool finite(const Eigen::Vector3d& v) { return v.allFinite(); }

// Keeps the nearer of two candidate hits; `t` must lie in (t_min, t_best).
inline void consider(double t, const Eigen::Vector3d& n_local, double t_min, double& t_best, Eigen::Vector3d& n_best) {
  if (t > t_min && t < t_best) {
    t_best = t;
    n_best = n_local;
  }
}

// Finite cylinder along z, centred, radius r, half length h, flat caps.
void cylinder_hits(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double r, double h, double t_min, double& t_best,
                   Eigen::Vector3d& n_best) {
  const double a = d.x() * d.x() + d.y() * d.y();
  if (a > kEps) {
    const double b = o.x() * d.x() + o.y() * d.y();
    const double c = o.x() * o.x() + o.y() * o.y() - r * r;
    const double disc = b * b - a * c;
    if (disc >= 0.0) {
      const double s = std::sqrt(disc);
      for (double t : {(-b - s) / a, (-b + s) / a}) {
        const double z = o.z() + t * d.z();
        if (std::abs(z) <= h) {
          const Eigen::Vector3d p = o + t * d;
          consider(t, Eigen::Vector3d(p.x() / r, p.y() / r, 0.0), t_min, t_best, n_best);
        }
      }
    }
  }
  if (std::abs(d.z()) > kEps) {
    for (double zc : {-h, h}) {
      const double t = (zc - o.z()) / d.z();
      const Eigen::Vector3d p = o + t * d;
      if (p.x() * p.x() + p.y() * p.y() <= r * r)
        consider(t, Eigen::Vector3d(0, 0, zc > 0 ? 1.0 : -1.0), t_min, t_best, n_best);
    }
  }
}

// Ray o + t d against each shape in its own frame: the nearer hit in
// (t_min, t_best) updates t_best and the local normal n_best.

// Plane z = 0, size_m wide along x and y (infinite when not finite).
void plane_hits(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const PlaneShape& p, double t_min, double& t_best,
                Eigen::Vector3d& n_best) {
  if (std::abs(d.z()) < kEps) return;
  const double t = -o.z() / d.z();
  const Eigen::Vector3d q = o + t * d;
  if (std::abs(q.x()) <= 0.5 * p.size_m.x() && std::abs(q.y()) <= 0.5 * p.size_m.y())
    consider(t, Eigen::Vector3d::UnitZ(), t_min, t_best, n_best);
}

// Centred box (slab test); from inside, the exit face.
void box_hits(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const BoxShape& b, double t_min, double t_max,
              double& t_best, Eigen::Vector3d& n_best) {
  const Eigen::Vector3d h = 0.5 * b.size_m;
  double t0 = -kInf, t1 = kInf;
  int a0 = -1, a1 = -1;
  double s0 = 0, s1 = 0;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(d[i]) < kEps) {
      if (o[i] < -h[i] || o[i] > h[i]) return;
      continue;
    }
    double ta = (-h[i] - o[i]) / d[i], tb = (h[i] - o[i]) / d[i];
    double sa = -1, sb = 1;
    if (ta > tb) {
      std::swap(ta, tb);
      std::swap(sa, sb);
    }
    if (ta > t0) {
      t0 = ta;
      a0 = i;
      s0 = sa;
    }
    if (tb < t1) {
      t1 = tb;
      a1 = i;
      s1 = sb;
    }
  }
  if (t0 > t1) return;
  if (a0 >= 0) {
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    n[a0] = s0;
    consider(t0, n, t_min, t_best, n_best);
  }
  if (a1 >= 0 && t_best == t_max) {  // origin inside: the exit face
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    n[a1] = s1;
    consider(t1, n, t_min, t_best, n_best);
  }
}

// Centred sphere: the first root in range.
void sphere_hits(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const SphereShape& s, double t_min, double& t_best,
                 Eigen::Vector3d& n_best) {
  const double b = o.dot(d);
  const double c = o.squaredNorm() - s.radius_m * s.radius_m;
  const double disc = b * b - c;
  if (disc < 0) return;
  const double q = std::sqrt(disc);
  for (double t : {-b - q, -b + q}) {
    if (t > t_min && t < t_best) {
      consider(t, (o + t * d) / s.radius_m, t_min, t_best, n_best);
      break;
    }
  }
}

// Slab test on the mesh's box, then Moller-Trumbore per triangle.
void mesh_hits(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const MeshShape& m, const Eigen::AlignedBox3d& box,
               double t_min, double& t_best, Eigen::Vector3d& n_best) {
  const Eigen::Vector3d inv = d.cwiseInverse();
  const Eigen::Vector3d ta = (box.min() - o).cwiseProduct(inv);
  const Eigen::Vector3d tb = (box.max() - o).cwiseProduct(inv);
  const double tn = ta.cwiseMin(tb).maxCoeff(), tf = ta.cwiseMax(tb).minCoeff();
  if (!(tn <= tf) || tf < t_min || tn > t_best) {
    // NaN from 0*inf (ray in a face plane) falls through to the exact test.
    if (!(std::isnan(tn) || std::isnan(tf))) return;
  }
  for (const auto& tri : m.triangles) {
    const Eigen::Vector3d& v0 = m.vertices[static_cast<std::size_t>(tri[0])];
    const Eigen::Vector3d e1 = m.vertices[static_cast<std::size_t>(tri[1])] - v0;
    const Eigen::Vector3d e2 = m.vertices[static_cast<std::size_t>(tri[2])] - v0;
    const Eigen::Vector3d p = d.cross(e2);
    const double det = e1.dot(p);
    if (std::abs(det) < 1e-15) continue;
    const double id = 1.0 / det;
    const Eigen::Vector3d s = o - v0;
    const double u = s.dot(p) * id;
    if (u < 0 || u > 1) continue;
    const Eigen::Vector3d q = s.cross(e1);
    const double v = d.dot(q) * id;
    if (v < 0 || u + v > 1) continue;
    const double t = e2.dot(q) * id;
    if (t > t_min && t < t_best) consider(t, e1.cross(e2).normalized(), t_min, t_best, n_best);
  }
}

}  // namespace

const char* shape_name(const Shape& s) {
  return std::visit(
      Overloaded{[](const PlaneShape&) { return "plane"; }, [](const BoxShape&) { return "box"; },
                 [](const SphereShape&) { return "sphere"; }, [](const CylinderShape&) { return "cylinder"; },
                 [](const RodShape&) { return "rod"; }, [](const MeshShape&) { return "mesh"; }},
      s);
}

common::Status validate_shape(const Shape& s) {
  return std::visit(Overloaded{[](const PlaneShape& p) -> common::Status {
                                 if (std::isnan(p.size_m.x()) || std::isnan(p.size_m.y()) || !(p.size_m.x() > 0) ||
                                     !(p.size_m.y() > 0))
                                   return common::Status::invalid("plane size_m must be > 0");
                                 return common::Status{};
                               },
                               [](const BoxShape& b) -> common::Status {
                                 if (!finite(b.size_m) || (b.size_m.array() <= 0.0).any())
                                   return common::Status::invalid("box size_m must be finite and > 0");
                                 return common::Status{};
                               },
                               [](const SphereShape& s) -> common::Status {
                                 if (!std::isfinite(s.radius_m) || s.radius_m <= 0)
                                   return common::Status::invalid("sphere radius_m must be finite and > 0");
                                 return common::Status{};
                               },
                               [](const CylinderShape& c) -> common::Status {
                                 if (!std::isfinite(c.radius_m) || c.radius_m <= 0)
                                   return common::Status::invalid("cylinder radius_m must be finite and > 0");
                                 if (!std::isfinite(c.length_m) || c.length_m <= 0)
                                   return common::Status::invalid("cylinder length_m must be finite and > 0");
                                 return common::Status{};
                               },
                               [](const RodShape& r) -> common::Status {
                                 if (!std::isfinite(r.radius_m) || r.radius_m <= 0)
                                   return common::Status::invalid("rod radius_m must be finite and > 0");
                                 if (!finite(r.p0) || !finite(r.p1))
                                   return common::Status::invalid("rod end points must be finite");
                                 if ((r.p1 - r.p0).norm() < 1e-9)
                                   return common::Status::invalid("rod end points p0 and p1 coincide");
                                 return common::Status{};
                               },
                               [](const MeshShape& m) -> common::Status {
                                 if (m.triangles.empty()) return common::Status::invalid("mesh has no triangles");
                                 for (const auto& v : m.vertices)
                                   if (!finite(v)) return common::Status::invalid("mesh vertex is not finite");
                                 const int n = static_cast<int>(m.vertices.size());
                                 for (std::size_t i = 0; i < m.triangles.size(); ++i) {
                                   const auto& t = m.triangles[i];
                                   if ((t.array() < 0).any() || (t.array() >= n).any())
                                     return common::Status::invalid("mesh triangle " + std::to_string(i) +
                                                                    " indexes a vertex that does not exist");
                                 }
                                 return common::Status{};
                               }},
                    s);
}

ObjectId World::add(Object o) {
  if (const common::Status why = validate_shape(o.shape); !why.ok()) {
    throw std::invalid_argument("object '" + o.name + "': " + why.message);
  }
  if (o.material < 0 || static_cast<std::size_t>(o.material) >= materials_.size()) {
    throw std::invalid_argument("object '" + o.name + "': unknown material id " + std::to_string(o.material));
  }
  if (!o.T_world_object.matrix().allFinite())
    throw std::invalid_argument("object '" + o.name + "': pose is not finite");
  Entry e;
  e.obj = std::move(o);
  refresh(e);
  objects_.push_back(std::move(e));
  return static_cast<ObjectId>(objects_.size() - 1);
}

void World::set_pose(ObjectId id, const Eigen::Isometry3d& T_world_object) {
  auto& e = objects_.at(static_cast<std::size_t>(id));
  if (!T_world_object.matrix().allFinite())
    throw std::invalid_argument("object '" + e.obj.name + "': pose is not finite");
  e.obj.T_world_object = T_world_object;
  refresh(e);
}

std::optional<ObjectId> World::find(std::string_view name) const {
  for (std::size_t i = 0; i < objects_.size(); ++i)
    if (objects_[i].obj.name == name) return static_cast<ObjectId>(i);
  return std::nullopt;
}

void World::refresh(Entry& e) {
  const auto& T = e.obj.T_world_object;
  e.T_object_world = T.inverse();
  e.centre_w = T.translation();
  std::visit(
      Overloaded{
          [&](const PlaneShape& p) {
            e.radius = (std::isinf(p.size_m.x()) || std::isinf(p.size_m.y())) ? kInf : 0.5 * p.size_m.norm();
          },
          [&](const BoxShape& b) { e.radius = 0.5 * b.size_m.norm(); },
          [&](const SphereShape& s) { e.radius = s.radius_m; },
          [&](const CylinderShape& c) { e.radius = std::hypot(c.radius_m, 0.5 * c.length_m); },
          [&](const RodShape& r) {
            const Eigen::Vector3d axis = r.p1 - r.p0;
            e.half_len = 0.5 * axis.norm();
            Eigen::Isometry3d L = Eigen::Isometry3d::Identity();
            L.linear() =
                Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), axis.normalized()).toRotationMatrix();
            L.translation() = 0.5 * (r.p0 + r.p1);
            e.T_world_local = T * L;
            e.T_local_world = e.T_world_local.inverse();
            e.centre_w = e.T_world_local.translation();
            e.radius = std::hypot(r.radius_m, e.half_len);
          },
          [&](const MeshShape& m) {
            e.mesh_box.setEmpty();
            for (const auto& v : m.vertices) e.mesh_box.extend(v);
            e.centre_w = T * e.mesh_box.center();
            e.radius = 0.5 * e.mesh_box.diagonal().norm() + 1e-9;
          }},
      e.obj.shape);
}

bool World::intersect(const Entry& e, const Ray& ray, double t_min, double t_max, Hit& hit) const {
  // Bounding-sphere rejection first: most objects miss most rays.
  if (std::isfinite(e.radius)) {
    const Eigen::Vector3d v = e.centre_w - ray.origin;
    const double tca = v.dot(ray.dir);
    const double d2 = v.squaredNorm() - tca * tca;
    if (d2 > e.radius * e.radius) return false;
    if (tca + e.radius < t_min || tca - e.radius > t_max) return false;
  }
  const bool is_rod = std::holds_alternative<RodShape>(e.obj.shape);
  const Eigen::Isometry3d& Tinv = is_rod ? e.T_local_world : e.T_object_world;
  const Eigen::Vector3d o = Tinv * ray.origin;
  const Eigen::Vector3d d = Tinv.linear() * ray.dir;
  double t_best = t_max;
  Eigen::Vector3d n_best = Eigen::Vector3d::Zero();

  std::visit(Overloaded{[&](const PlaneShape& p) { plane_hits(o, d, p, t_min, t_best, n_best); },
                        [&](const BoxShape& b) { box_hits(o, d, b, t_min, t_max, t_best, n_best); },
                        [&](const SphereShape& s) { sphere_hits(o, d, s, t_min, t_best, n_best); },
                        [&](const CylinderShape& c) {
                          cylinder_hits(o, d, c.radius_m, 0.5 * c.length_m, t_min, t_best, n_best);
                        },
                        [&](const RodShape& r) { cylinder_hits(o, d, r.radius_m, e.half_len, t_min, t_best, n_best); },
                        [&](const MeshShape& m) { mesh_hits(o, d, m, e.mesh_box, t_min, t_best, n_best); }},
             e.obj.shape);

  if (!(t_best < t_max)) return false;
  const Eigen::Isometry3d& Tw = is_rod ? e.T_world_local : e.obj.T_world_object;
  Eigen::Vector3d n = (Tw.linear() * n_best).normalized();
  if (n.dot(ray.dir) > 0) n = -n;  // two-sided: face the viewer
  hit.t_m = t_best;
  hit.point = ray.origin + t_best * ray.dir;
  hit.normal = n;
  hit.material = e.obj.material;
  return true;
}

std::optional<Hit> World::raycast(const Ray& ray, double t_min, double t_max) const {
  Hit best;
  bool any = false;
  for (std::size_t i = 0; i < objects_.size(); ++i) {
    Hit h;
    if (intersect(objects_[i], ray, t_min, any ? best.t_m : t_max, h)) {
      h.object = static_cast<ObjectId>(i);
      best = h;
      any = true;
    }
  }
  if (!any) return std::nullopt;
  return best;
}

bool World::occluded(const Eigen::Vector3d& a, const Eigen::Vector3d& b) const {
  const Eigen::Vector3d v = b - a;
  const double len = v.norm();
  if (len < 1e-9) return false;
  const Ray r{a, v / len};
  const double eps = 1e-6;
  for (const auto& e : objects_) {
    Hit h;
    if (intersect(e, r, eps, len - eps, h)) return true;
  }
  return false;
}

std::vector<ObjectId> World::containing(const Eigen::Vector3d& p) const {
  std::vector<ObjectId> out;
  for (std::size_t i = 0; i < objects_.size(); ++i) {
    const auto& e = objects_[i];
    const bool in =
        std::visit(Overloaded{[&](const PlaneShape&) { return false; },
                              [&](const BoxShape& b) {
                                return ((e.T_object_world * p).cwiseAbs().array() < 0.5 * b.size_m.array()).all();
                              },
                              [&](const SphereShape& s) { return (e.T_object_world * p).norm() < s.radius_m; },
                              [&](const CylinderShape& c) {
                                const Eigen::Vector3d q = e.T_object_world * p;
                                return q.head<2>().norm() < c.radius_m && std::abs(q.z()) < 0.5 * c.length_m;
                              },
                              [&](const RodShape& r) {
                                const Eigen::Vector3d q = e.T_local_world * p;
                                return q.head<2>().norm() < r.radius_m && std::abs(q.z()) < e.half_len;
                              },
                              [&](const MeshShape&) { return false; }},
                   e.obj.shape);
    if (in) out.push_back(static_cast<ObjectId>(i));
  }
  return out;
}

}  // namespace tinyline::sim
