// SPDX-License-Identifier: Apache-2.0
// The Hydrus chain in the world, and its scene generator "hydrus".
#include <sim/scenes/hydrus.hpp>

#include <cmath>
#include <filesystem>
#include <stdexcept>

namespace tinyline::sim {

namespace {
constexpr double kDeg = 3.14159265358979323846 / 180.0;
}

common::Status HydrusChainParams::validate() const {
  if (links < 1 || links > 32) return common::Status::invalid("links must be 1..32, got " + std::to_string(links));
  if (!(link_length_m > 0.0)) return common::Status::invalid("link_length_m must be > 0");
  if (!(link_width_m > 0.0)) return common::Status::invalid("link_width_m must be > 0");
  if (!(link_thickness_m > 0.0)) return common::Status::invalid("link_thickness_m must be > 0");
  if (!std::isfinite(height_m)) return common::Status::invalid("height_m must be finite");
  if (!sensor_mount_m.allFinite() || !std::isfinite(sensor_yaw_rad))
    return common::Status::invalid("sensor mount must be finite");
  return common::Status{};
}

Eigen::Isometry3d planar_sensor_frame(const Eigen::Vector2d& origin_m, double yaw_rad, double height_m,
                                      bool line_axis_left) {
  const Eigen::Vector3d z(std::cos(yaw_rad), std::sin(yaw_rad), 0.0);  // optical axis
  const double side = line_axis_left ? 1.0 : -1.0;
  const Eigen::Vector3d x = side * Eigen::Vector3d(-std::sin(yaw_rad), std::cos(yaw_rad), 0.0);  // along the line
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = x;
  T.linear().col(1) = z.cross(x);
  T.linear().col(2) = z;
  T.translation() = Eigen::Vector3d(origin_m.x(), origin_m.y(), height_m);
  return T;
}

HydrusPoses hydrus_poses(const HydrusChainParams& chain, const HydrusState& state) {
  if (const common::Status why = chain.validate(); !why.ok()) throw std::invalid_argument("hydrus: " + why.message);
  if (state.joints_rad.size() != static_cast<std::size_t>(chain.links - 1))
    throw std::invalid_argument("hydrus: " + std::to_string(state.joints_rad.size()) + " joint angles for " +
                                std::to_string(chain.links - 1) + " joints");
  HydrusPoses p;
  Eigen::Isometry2d T = Eigen::Isometry2d::Identity();
  T.translation() = state.base_xy_m;
  T.linear() = Eigen::Rotation2Dd(state.base_yaw_rad).toRotationMatrix();
  for (int i = 0; i < chain.links; ++i) {
    if (i > 0) {
      Eigen::Isometry2d step = Eigen::Isometry2d::Identity();
      step.translation() = Eigen::Vector2d(chain.link_length_m, 0.0);
      step.linear() = Eigen::Rotation2Dd(state.joints_rad[static_cast<std::size_t>(i - 1)]).toRotationMatrix();
      T = T * step;
    }
    p.T_world_link.push_back(T);
    const Eigen::Vector2d c = T * Eigen::Vector2d(0.5 * chain.link_length_m, 0.0);
    const double yaw = Eigen::Rotation2Dd(T.linear()).angle();
    Eigen::Isometry3d box = Eigen::Isometry3d::Identity();
    box.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    box.translation() = Eigen::Vector3d(c.x(), c.y(), chain.height_m);
    p.T_world_link_box.push_back(box);
    p.T_world_sensor.push_back(planar_sensor_frame(T * chain.sensor_mount_m, yaw + chain.sensor_yaw_rad, chain.height_m,
                                                   chain.line_axis_left));
  }
  return p;
}

void add_hydrus(const HydrusChainParams& chain, const HydrusState& state, const SensorParams& sensor,
                const std::string& sensor_config_file, Scene& scene) {
  const HydrusPoses poses = hydrus_poses(chain, state);
  const auto material = scene.world.materials().find(chain.material);
  if (!material) throw std::invalid_argument("hydrus: unknown material '" + chain.material + "'");
  for (int i = 0; i < chain.links; ++i) {
    Object o;
    o.name = chain.link_name(i);
    o.shape = BoxShape{Eigen::Vector3d(chain.link_length_m, chain.link_width_m, chain.link_thickness_m)};
    o.T_world_object = poses.T_world_link_box[static_cast<std::size_t>(i)];
    o.material = *material;
    scene.world.add(std::move(o));
  }
  for (int i = 0; i < chain.links; ++i) {
    SensorMount m;
    m.name = chain.sensor_name(i);
    m.params = sensor;
    m.config_file = sensor_config_file;
    m.T_world_sensor = poses.T_world_sensor[static_cast<std::size_t>(i)];
    if (scene.sensor(m.name)) throw std::invalid_argument("hydrus: a sensor named '" + m.name + "' already exists");
    if (const common::Status why = scene.check_sensor_placement(m); !why.ok())
      throw std::invalid_argument("hydrus: sensor '" + m.name + "': " + why.message);
    scene.sensors.push_back(std::move(m));
  }
}

namespace {

void make_hydrus(const YamlNode& p, Scene& scene) {
  p.check_keys({"type", "name", "links", "link_length_m", "link_width_m", "link_thickness_m", "height_m", "base",
                "joints_deg", "sensor_mount_m", "sensor_yaw_deg", "line_axis", "sensor_config", "sensor_params",
                "material"});
  HydrusChainParams c;
  c.name = p.get_string("name", "");
  c.links = p.get_int("links", c.links);
  c.link_length_m = p.get_double("link_length_m", c.link_length_m);
  c.link_width_m = p.get_double("link_width_m", c.link_width_m);
  c.link_thickness_m = p.get_double("link_thickness_m", c.link_thickness_m);
  c.height_m = p.get_double("height_m", c.height_m);
  if (auto m = p.find("sensor_mount_m")) c.sensor_mount_m = m->as_vec2();
  c.sensor_yaw_rad = p.get_double("sensor_yaw_deg", c.sensor_yaw_rad / kDeg) * kDeg;
  const std::string axis = p.get_string("line_axis", "left");
  if (axis != "left" && axis != "right") p.at("line_axis").fail("must be left or right, got '" + axis + "'");
  c.line_axis_left = axis == "left";
  c.material = p.get_string("material", c.material);
  if (const common::Status why = c.validate(); !why.ok()) p.fail(why.message);

  HydrusState s;
  if (auto b = p.find("base")) {
    b->check_keys({"xy_m", "yaw_deg"});
    if (auto xy = b->find("xy_m")) s.base_xy_m = xy->as_vec2();
    s.base_yaw_rad = b->get_double("yaw_deg", 0.0) * kDeg;
  }
  s.joints_rad.assign(static_cast<std::size_t>(c.links - 1), 0.0);
  if (auto j = p.find("joints_deg")) {
    const auto v = j->as_doubles();
    if (v.size() != s.joints_rad.size())
      j->fail("needs " + std::to_string(s.joints_rad.size()) + " angles (links - 1), got " + std::to_string(v.size()));
    for (std::size_t i = 0; i < v.size(); ++i) s.joints_rad[i] = v[i] * kDeg;
  }

  SensorParams sensor;
  std::string config_file;
  if (auto cfg = p.find("sensor_config")) {
    std::filesystem::path path = cfg->as_string();
    if (path.is_relative()) path = std::filesystem::path(cfg->file()).parent_path() / path;
    if (!std::filesystem::exists(path)) cfg->fail("sensor config '" + path.string() + "' does not exist");
    config_file = path.string();
    sensor = load_sensor_params(config_file);
  }
  if (auto sp = p.find("sensor_params")) apply_sensor_params(*sp, sensor);
  try {
    add_hydrus(c, s, sensor, config_file, scene);
  } catch (const std::invalid_argument& e) {
    p.fail(e.what());
  }
}

}  // namespace

}  // namespace tinyline::sim

TINYLINE_SIM_SCENE_GENERATOR(hydrus) {
  registry.add("hydrus",
               "the multi-link aerial robot Hydrus: a planar chain of links (boxes) with one TOF line sensor per link "
               "(thesis 6.2)",
               &make_hydrus);
}
