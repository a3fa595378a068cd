// SPDX-License-Identifier: Apache-2.0
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include <sys/stat.h>
#include <unistd.h>

#include <sim/scene.hpp>

using namespace tinyline::sim;

namespace {

// Expects a ConfigError whose message names the line and the field.
void expect_error(const std::string& yaml, int line, const std::string& field, const std::string& fragment) {
  try {
    (void)load_scene_string(yaml, "test.yaml", ".");
    FAIL() << "no error for:\n" << yaml;
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.file(), "test.yaml");
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_EQ(e.field(), field) << e.what();
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("test.yaml:" + std::to_string(line)), std::string::npos) << e.what();
  }
}

std::string src(const std::string& rel) { return std::string(TINYLINE_SOURCE_DIR) + "/" + rel; }

}  // namespace

TEST(Scene, LoadsObjectsSensorsAndTruth) {
  const Scene s = load_scene_string(R"(
name: demo
objects:
  - {name: wall, shape: plane, material: wall_paint, pose: {xyz: [0, 0, 1.5]}}
  - {name: ball, shape: sphere, radius_m: 0.04, material: tomato_red, pose: {xyz: [0, 0, 0.5]}}
  - {name: stick, shape: rod, radius_m: 0.004, p0: [0, -0.1, 0.4], p1: [0, 0.1, 0.4], material: wood}
sensors:
  - {name: laser, pose: {xyz: [0, 0, 0]}, params: {seed: 9, lens: {focal_mm: 3.6}}}
truth: {ball_radius_m: 0.04, ball_centre: [0, 0, 0.5]}
)",
                                    "demo.yaml", ".");
  EXPECT_EQ(s.name, "demo");
  EXPECT_EQ(s.world.size(), 3u);
  ASSERT_EQ(s.sensors.size(), 1u);
  EXPECT_EQ(s.sensors[0].params.seed, 9u);
  EXPECT_DOUBLE_EQ(s.sensors[0].params.lens.focal_mm, 3.6);
  EXPECT_EQ(s.truth.at("ball_centre").size(), 3u);
  const auto h = s.world.raycast({{0, 0, 0}, {0, 0, 1}});
  ASSERT_TRUE(h);
  EXPECT_EQ(s.world.object(h->object).name, "stick");
}

TEST(Scene, CustomMaterialAndGenerator) {
  const Scene s = load_scene_string(R"(
materials:
  - {name: shiny_red, like: metal_pan, rgb: [0.9, 0.1, 0.1]}
objects:
  - {name: plate, shape: box, size_m: [0.2, 0.2, 0.01], material: shiny_red, pose: {xyz: [0, 0, 0.5]}}
generators:
  - {type: room, size_m: [3, 3, 3]}
sensors:
  - {name: laser}
)",
                                    "m.yaml", ".");
  EXPECT_EQ(s.world.size(), 7u);  // plate + 6 walls
  const auto& m = s.world.materials().get(*s.world.materials().find("shiny_red"));
  EXPECT_GT(m.specular, 0.0);
  // Every ray from the centre ends on a wall.
  for (double a = -3.0; a <= 3.0; a += 0.5) {
    EXPECT_TRUE(s.world.raycast({{0, 0, 0}, Eigen::Vector3d(std::sin(a), 0.3, std::cos(a)).normalized()})) << a;
  }
}

TEST(Scene, ErrorsNameFileLineAndField) {
  expect_error("objects:\n  - {name: a, shape: sphere, radius_m: 0.1, material: wood, colour: red}\n", 2,
               "objects[0].colour", "unknown key 'colour'");
  expect_error("objects:\n  - name: a\n    shape: sphere\n    radius_m: -0.02\n    material: wood\n", 4,
               "objects[0].radius_m", "must be > 0");
  expect_error("objects:\n  - {name: a, shape: cone, material: wood}\n", 2, "objects[0].shape", "unknown shape 'cone'");
  expect_error("objects:\n  - {name: a, shape: sphere, radius_m: 0.1, material: unobtainium}\n", 2,
               "objects[0].material", "unknown material");
  expect_error(
      "objects:\n  - {name: a, shape: sphere, radius_m: 0.1, material: wood}\n"
      "  - {name: a, shape: sphere, radius_m: 0.1, material: wood}\n",
      3, "objects[1].name", "duplicate");
  expect_error("objects:\n  - {name: a, shape: box, size_m: [1, 2], material: wood}\n", 2, "objects[0].size_m",
               "expected 3 numbers");
  expect_error("objectz: []\n", 1, "objectz", "did you mean 'objects'");
  expect_error("objects:\n  - {name: a, shape: sphere, radius_m: abc, material: wood}\n", 2, "objects[0].radius_m",
               "expected a number");
}

TEST(Scene, SensorInsideAnObjectIsAnError) {
  expect_error(R"(objects:
  - {name: crate, shape: box, size_m: [0.5, 0.5, 0.5], material: wood, pose: {xyz: [0, 0, 0]}}
sensors:
  - name: laser
    pose: {xyz: [0.1, 0, 0]}
)",
               5, "sensors[0].pose", "inside object 'crate'");
}

TEST(Scene, SensorParamErrorsPointIntoTheScene) {
  expect_error("sensors:\n  - name: laser\n    params: {lens: {focal_mm: -3}}\n", 3, "sensors[0].params.lens.focal_mm",
               "must be in");
  expect_error("sensors:\n  - name: laser\n    params: {pixel: {kneee: 3}}\n", 3, "sensors[0].params.pixel.kneee",
               "did you mean 'knee'");
  expect_error("sensors:\n  - name: laser\n    params: {effects: [{type: gremlins}]}\n", 3,
               "sensors[0].params.effects[0].type", "unknown effect type");
  expect_error("sensors:\n  - name: laser\n    params: {acquisition: {raw_pulses: [20, 15, 700]}}\n", 3,
               "sensors[0].params.acquisition.raw_pulses[1]", "multiple of 10");
}

TEST(Scene, SyntaxErrorAndMissingFile) {
  try {
    (void)load_scene_string("objects: [\n  {name: a\n", "broken.yaml", ".");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.file(), "broken.yaml");
    EXPECT_GT(e.line(), 0);
    EXPECT_NE(std::string(e.what()).find("syntax"), std::string::npos);
  }
  EXPECT_THROW((void)load_scene("/nonexistent/scene.yaml"), ConfigError);
}

// A FIFO as a scene (or as a sensor file a scene names) used to block the
// load for ever, /dev/zero to be read until memory ran out.
TEST(Scene, AFifoOrADeviceAsSceneOrSensorFileIsRefusedNamingIt) {
  const auto dir = std::filesystem::temp_directory_path() / ("tinyline_sim_scene_fifo_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string fifo = (dir / "pipe.yaml").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  auto error_of = [](const std::string& path) -> std::string {
    try {
      (void)load_scene(path);
    } catch (const ConfigError& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_NE(error_of(fifo).find("scene '" + fifo + "' is a FIFO, not a regular file"), std::string::npos)
      << error_of(fifo);
  EXPECT_NE(error_of("/dev/zero").find("scene '/dev/zero' is a character device, not a regular file"),
            std::string::npos);
  const std::string scene = (dir / "scene.yaml").string();
  std::ofstream(scene) << "sensors:\n  - name: laser\n    config: pipe.yaml\n";
  EXPECT_NE(error_of(scene).find("sensor file '" + fifo + "' is a FIFO"), std::string::npos) << error_of(scene);
  std::filesystem::remove_all(dir);
}

TEST(Scene, SensorFilesInheritAndShippedFilesLoad) {
  const auto dir = std::filesystem::temp_directory_path() / "tinyline_sim_scene_test";
  std::filesystem::create_directories(dir);
  {
    std::ofstream(dir / "base.yaml") << "name: base\nlens: {focal_mm: 3.6}\npixel: {read_noise: 0.5}\n";
    std::ofstream(dir / "child.yaml") << "base: base.yaml\nname: child\npixel: {read_noise: 0.7}\n";
    std::ofstream(dir / "scene.yaml") << "sensors:\n  - {name: s, config: child.yaml}\n";
  }
  const Scene s = load_scene((dir / "scene.yaml").string());
  ASSERT_EQ(s.sensors.size(), 1u);
  EXPECT_EQ(s.sensors[0].params.name, "child");
  EXPECT_DOUBLE_EQ(s.sensors[0].params.lens.focal_mm, 3.6);
  EXPECT_DOUBLE_EQ(s.sensors[0].params.pixel.read_noise, 0.7);
  std::filesystem::remove_all(dir);

  // Every shipped sensor and scene file loads.
  for (const char* sub : {"sim/config/sensors", "sim/config/scenes"}) {
    if (!std::filesystem::exists(src(sub))) continue;  // no scene files shipped yet
    for (const auto& f : std::filesystem::directory_iterator(src(sub))) {
      if (f.path().extension() != ".yaml") continue;
      if (std::string(sub).ends_with("sensors")) {
        EXPECT_NO_THROW((void)load_sensor_params(f.path().string())) << f.path();
      } else {
        EXPECT_NO_THROW((void)load_scene(f.path().string())) << f.path();
      }
    }
  }
}

TEST(Scene, SensorParamsRoundTripThroughYaml) {
  SensorParams p;
  p.effects.push_back(FixedPatternEffect{120.0, 40.0, 3});
  MaterialBiasEffect mb;
  mb.path_mm["ic_foam"] = 90.0;
  p.effects.emplace_back(std::move(mb));
  p.effects.push_back(CovariateEffect{});
  const std::string text = to_yaml(p);
  SensorParams q;
  apply_sensor_params(YamlNode::load_string(text, "roundtrip"), q);
  EXPECT_EQ(to_yaml(q), text);
}
