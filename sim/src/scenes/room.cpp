// SPDX-License-Identifier: Apache-2.0
// Generator "room": the six walls of a box-shaped room around the origin, so a
// scene has a background at a known distance (every ray ends somewhere).
#include <sim/scene.hpp>

namespace {

void make_room(const tinyline::sim::YamlNode& p, tinyline::sim::Scene& scene) {
  using namespace tinyline::sim;
  p.check_keys({"type", "name", "size_m", "centre", "material", "floor_material"});
  const std::string name = p.get_string("name", "room");
  Eigen::Vector3d size(4.0, 4.0, 2.5);
  if (auto s = p.find("size_m")) {
    size = s->as_vec3();
    if (!(size.array() > 0.0).all()) s->fail("sizes must be > 0");
  }
  const Eigen::Vector3d centre = p.find("centre") ? p.at("centre").as_vec3() : Eigen::Vector3d::Zero();
  auto material = [&](const char* key, const char* fallback) {
    const std::string m = p.get_string(key, fallback);
    const auto id = scene.world.materials().find(m);
    if (!id) p.at(key).fail("unknown material '" + m + "'");
    return *id;
  };
  const MaterialId wall = material("material", "wall_paint");
  const MaterialId floor = p.has("floor_material") ? material("floor_material", "grey_matte") : wall;
  // A wall is a plane through centre +- half size along one axis, facing inwards.
  struct W {
    const char* suffix;
    Eigen::Vector3d normal;
  };
  const W walls[] = {{"_xp", {1, 0, 0}},  {"_xn", {-1, 0, 0}}, {"_yp", {0, 1, 0}},
                     {"_yn", {0, -1, 0}}, {"_zp", {0, 0, 1}},  {"_zn", {0, 0, -1}}};
  for (const auto& w : walls) {
    const int axis =
        w.normal.cwiseAbs().maxCoeff() == std::abs(w.normal.x()) ? 0 : (std::abs(w.normal.y()) > 0.5 ? 1 : 2);
    Object o;
    o.name = name + w.suffix;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), w.normal).toRotationMatrix();
    T.translation() = centre + 0.5 * size[axis] * w.normal;
    o.T_world_object = T;
    // Square walls as large as the room's largest side: the parts beyond the
    // corners lie outside the room, where no ray from inside reaches them first.
    const double side = 1.01 * size.maxCoeff();
    o.shape = PlaneShape{Eigen::Vector2d(side, side)};
    o.material = (axis == 2 && w.normal.z() < 0) ? floor : wall;
    scene.world.add(std::move(o));
  }
}

}  // namespace

TINYLINE_SIM_SCENE_GENERATOR(room) {
  registry.add("room", "six walls of a box room: size_m [x,y,z], centre, material, floor_material", &make_room);
}
