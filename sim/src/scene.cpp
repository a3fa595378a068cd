// SPDX-License-Identifier: Apache-2.0
#include <sim/scene.hpp>

#include <filesystem>
#include <fstream>
#include <mutex>
#include <set>
#include <sstream>

namespace tinyline::sim {

namespace {

namespace fs = std::filesystem;

Material read_material(const YamlNode& n, const MaterialLibrary& lib) {
  n.check_keys({"name", "like", "albedo", "specular", "specular_exponent", "rgb"});
  Material m;
  if (auto like = n.find("like")) {
    const auto id = lib.find(like->as_string());
    if (!id) like->fail("unknown material '" + like->as_string() + "'");
    m = lib.get(*id);
  }
  m.name = n.get_string("name");
  if (m.name.empty()) n.at("name").fail("must not be empty");
  m.albedo = n.in_range("albedo", m.albedo, 0.0, 1.0);
  m.specular = n.non_negative("specular", m.specular);
  m.specular_exponent = n.in_range("specular_exponent", m.specular_exponent, 0.0, 100000.0);
  if (auto rgb = n.find("rgb")) {
    m.rgb = rgb->as_vec3();
    if ((m.rgb.array() < 0.0).any() || (m.rgb.array() > 1.0).any()) rgb->fail("rgb components must be in [0, 1]");
  }
  m.reflectance_figure = std::numeric_limits<double>::quiet_NaN();
  return m;
}

Shape read_shape(const YamlNode& n, const std::string& type) {
  if (type == "plane") {
    n.check_keys({"name", "shape", "material", "pose", "size_m"});
    PlaneShape p;
    if (auto s = n.find("size_m")) {
      p.size_m = s->as_vec2();
      if (!(p.size_m.array() > 0.0).all()) s->fail("sizes must be > 0");
    }
    return p;
  }
  if (type == "box") {
    n.check_keys({"name", "shape", "material", "pose", "size_m"});
    BoxShape b;
    const YamlNode s = n.at("size_m");
    b.size_m = s.as_vec3();
    if (!(b.size_m.array() > 0.0).all()) s.fail("sizes must be > 0");
    return b;
  }
  if (type == "sphere") {
    n.check_keys({"name", "shape", "material", "pose", "radius_m"});
    return SphereShape{n.positive("radius_m")};
  }
  if (type == "cylinder") {
    n.check_keys({"name", "shape", "material", "pose", "radius_m", "length_m"});
    return CylinderShape{n.positive("radius_m"), n.positive("length_m")};
  }
  if (type == "rod") {
    n.check_keys({"name", "shape", "material", "pose", "radius_m", "p0", "p1"});
    RodShape r;
    r.radius_m = n.positive("radius_m");
    r.p0 = n.at("p0").as_vec3();
    r.p1 = n.at("p1").as_vec3();
    if ((r.p1 - r.p0).norm() < 1e-9) n.at("p1").fail("rod end points p0 and p1 coincide");
    return r;
  }
  if (type == "mesh") {
    n.check_keys({"name", "shape", "material", "pose", "vertices", "triangles"});
    MeshShape m;
    for (const auto& v : n.at("vertices").items()) m.vertices.push_back(v.as_vec3());
    for (const auto& t : n.at("triangles").items()) {
      const auto idx = t.as_doubles(3);
      Eigen::Vector3i tri;
      for (int k = 0; k < 3; ++k) {
        if (idx[static_cast<std::size_t>(k)] != std::floor(idx[static_cast<std::size_t>(k)]) ||
            idx[static_cast<std::size_t>(k)] < 0 ||
            idx[static_cast<std::size_t>(k)] >= static_cast<double>(m.vertices.size()))
          t.fail("vertex index out of range (the mesh has " + std::to_string(m.vertices.size()) + " vertices)");
        tri[k] = static_cast<int>(idx[static_cast<std::size_t>(k)]);
      }
      m.triangles.push_back(tri);
    }
    if (m.triangles.empty()) n.at("triangles").fail("a mesh needs at least one triangle");
    return m;
  }
  n.at("shape").fail("unknown shape '" + type + "' (known: plane, box, sphere, cylinder, rod, mesh)");
}

void read_objects(const YamlNode& list, Scene& scene, std::set<std::string>& names) {
  for (const auto& n : list.items()) {
    n.require_map();
    Object o;
    o.name = n.get_string("name");
    if (o.name.empty()) n.at("name").fail("must not be empty");
    if (!names.insert(o.name).second) n.at("name").fail("duplicate object name '" + o.name + "'");
    const std::string type = n.get_string("shape");
    o.shape = read_shape(n, type);
    const YamlNode mat = n.at("material");
    const auto id = scene.world.materials().find(mat.as_string());
    if (!id) mat.fail("unknown material '" + mat.as_string() + "'");
    o.material = *id;
    if (auto pose = n.find("pose")) o.T_world_object = pose->as_pose();
    try {
      scene.world.add(std::move(o));
    } catch (const std::invalid_argument& e) {
      n.fail(e.what());
    }
  }
}

void read_sensors(const YamlNode& list, Scene& scene, const std::string& base_dir) {
  std::set<std::string> names;
  for (const auto& n : list.items()) {
    n.check_keys({"name", "config", "pose", "params"});
    SensorMount m;
    m.name = n.get_string("name");
    if (m.name.empty()) n.at("name").fail("must not be empty");
    if (!names.insert(m.name).second) n.at("name").fail("duplicate sensor name '" + m.name + "'");
    if (auto c = n.find("config")) {
      fs::path p = c->as_string();
      if (p.is_relative()) p = fs::path(base_dir) / p;
      if (!fs::exists(p)) c->fail("sensor config '" + p.string() + "' does not exist");
      m.config_file = p.string();
      m.params = load_sensor_params(m.config_file);
    }
    if (auto params = n.find("params")) apply_sensor_params(*params, m.params);
    if (auto pose = n.find("pose")) m.T_world_sensor = pose->as_pose();
    if (const common::Status why = scene.check_sensor_placement(m); !why.ok()) {
      (n.find("pose") ? *n.find("pose") : n).fail(why.message);
    }
    scene.sensors.push_back(std::move(m));
  }
}

Scene parse(const YamlNode& root, const std::string& base_dir) {
  root.require_map();
  root.check_keys({"name", "description", "materials", "objects", "sensors", "generators", "truth"});
  Scene scene;
  scene.source_file = root.file();
  scene.name = root.get_string("name", "");
  scene.description = root.get_string("description", "");
  if (auto mats = root.find("materials")) {
    for (const auto& m : mats->items()) scene.world.materials().add(read_material(m, scene.world.materials()));
  }
  std::set<std::string> names;
  if (auto objs = root.find("objects")) read_objects(*objs, scene, names);
  if (auto gens = root.find("generators")) {
    for (const auto& g : gens->items()) {
      g.require_map();
      const std::string type = g.get_string("type");
      const SceneGenerator* fn = scene_generators().find(type);
      if (!fn) {
        std::string known;
        for (const auto& [t, d] : scene_generators().list()) known += (known.empty() ? "" : ", ") + t;
        g.at("type").fail("unknown generator '" + type + "' (known: " + (known.empty() ? "none" : known) + ")");
      }
      const std::size_t before = scene.world.size();
      (*fn)(g, scene);
      for (std::size_t i = before; i < scene.world.size(); ++i) {
        const auto& name = scene.world.object(static_cast<ObjectId>(i)).name;
        if (!names.insert(name).second) g.fail("generator made an object named '" + name + "', which already exists");
      }
    }
  }
  if (auto truth = root.find("truth")) {
    truth->require_map();
    for (const auto& k : truth->keys()) {
      const YamlNode v = truth->at(k);
      scene.truth[k] = v.is_sequence() ? v.as_doubles() : std::vector<double>{v.as_double()};
    }
  }
  // Sensors last: the placement check needs every object.
  if (auto sensors = root.find("sensors")) read_sensors(*sensors, scene, base_dir);
  return scene;
}

}  // namespace

const SensorMount* Scene::sensor(std::string_view n) const {
  for (const auto& s : sensors)
    if (s.name == n) return &s;
  return nullptr;
}

common::Status Scene::check_sensor_placement(const SensorMount& m) const {
  const Eigen::Vector3d receiver = m.T_world_sensor.translation();
  const Eigen::Vector3d emitter = m.T_world_sensor * Eigen::Vector3d(m.params.emitter.baseline_m, 0, 0);
  for (const auto& [what, p] : {std::pair{"receiver", receiver}, std::pair{"emitter", emitter}}) {
    const auto inside = world.containing(p);
    if (!inside.empty()) {
      return common::Status::invalid(std::string("sensor '") + m.name + "' " + what + " is inside object '" +
                                     world.object(inside.front()).name + "'");
    }
  }
  return {};
}

Scene load_scene(const std::string& path) {
  const YamlNode root = YamlNode::load_file(path, "scene");
  return parse(root, fs::path(path).parent_path().string());
}

Scene load_scene_string(const std::string& text, const std::string& source_name, const std::string& base_dir) {
  return parse(YamlNode::load_string(text, source_name), base_dir);
}

void SceneGeneratorRegistry::add(std::string type, std::string description, SceneGenerator fn) {
  for (const auto& e : entries_)
    if (e.type == type) throw std::invalid_argument("scene generator '" + type + "' registered twice");
  entries_.push_back({std::move(type), std::move(description), std::move(fn)});
}

const SceneGenerator* SceneGeneratorRegistry::find(std::string_view type) const {
  for (const auto& e : entries_)
    if (e.type == type) return &e.fn;
  return nullptr;
}

std::vector<std::pair<std::string, std::string>> SceneGeneratorRegistry::list() const {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& e : entries_) out.emplace_back(e.type, e.description);
  return out;
}

SceneGeneratorRegistry& scene_generators() {
  static SceneGeneratorRegistry registry;
  static std::once_flag once;
  std::call_once(once, [] { detail::register_builtin_scene_generators(registry); });
  return registry;
}

}  // namespace tinyline::sim
