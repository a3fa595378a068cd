// SPDX-License-Identifier: Apache-2.0
// rgbd_folder_camera: a folder of frames played as a camera on stepped sim
// time (no sleeps): rate, order, loop, pose, bad frames skipped by name, a
// folder that cannot be opened stops the start.
#include <filesystem>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include <tinyline/bus/testing.hpp>

#include "tomato_reasoning/io/rgbd_files.hpp"
#include "tomato_reasoning/nodes/nodes.hpp"
#include "tomato_reasoning/nodes/register.hpp"

namespace bus = tinyline::bus;
namespace tr = tinyline::tomato_reasoning;
using ::testing::HasSubstr;
using tinyline::geometry_msgs::msg::PoseStamped;
using tinyline::sensor_msgs::msg::PointCloud2;

namespace {

/// Frames 4 x 3 px whose every depth pixel is `mm` of the frame (1000, 2000, ...).
struct Frames {
  bus::testing::TempDir dir;
  explicit Frames(int n) {
    std::filesystem::create_directories(dir.path / "rgb");
    std::filesystem::create_directories(dir.path / "depth");
    tr::io::CameraIntrinsics k;
    k.width = 4, k.height = 3, k.fx = k.fy = 5, k.cx = 1.5, k.cy = 1;
    tr::io::write_intrinsics(dir / "intrinsics.yaml", k);
    for (int i = 0; i < n; ++i) {
      const std::string name = "00000" + std::to_string(i) + ".png";
      cv::imwrite(dir / ("rgb/" + name), cv::Mat(3, 4, CV_8UC3, cv::Scalar(0, 0, 200)));
      cv::imwrite(dir / ("depth/" + name), cv::Mat(3, 4, CV_16UC1, cv::Scalar(1000 * (i + 1))));
    }
  }
};

float first_z(const PointCloud2& m) {
  tr::ColorCloud c;
  EXPECT_EQ(tr::nodes::to_core(m, c), "");
  return c.xyz.at(0).z();
}

struct Rig : bus::testing::NodeRig {
  Rig() : NodeRig({&tr::register_nodes}, bus::Time::from_seconds(100)) {}
  void run_until(double s) { ex.advance_to(bus::Time::from_seconds(s)); }
};

}  // namespace

TEST(RgbdFolderCamera, PlaysTheFramesInNameOrderAtItsRateThenStops) {
  Frames f(3);
  Rig rig;
  auto& clouds = rig.collect<PointCloud2>("cloud");
  bus::NodeOptions o;
  o.name = "camera";
  o.param("folder", f.dir.path.string()).param("rate_hz", 2.0).param("frame_id", std::string("cam_optical"));
  rig.add("tomato_reasoning", "rgbd_folder_camera", o);
  rig.run_until(100.9);
  ASSERT_EQ(clouds.size(), 1u);  // one period (0.5 s) after start
  rig.run_until(110);
  ASSERT_EQ(clouds.size(), 3u);  // then no more: loop is off
  for (int i = 0; i < 3; ++i) EXPECT_FLOAT_EQ(first_z(*clouds[std::size_t(i)]), float(i + 1));
  EXPECT_EQ(clouds[0]->header.frame_id, "cam_optical");
  EXPECT_EQ(clouds[0]->width, 4u);
  EXPECT_EQ(clouds[0]->height, 3u);
  EXPECT_EQ(clouds[1]->header.stamp.sec * 1000000000ll + clouds[1]->header.stamp.nanosec -
                (clouds[0]->header.stamp.sec * 1000000000ll + clouds[0]->header.stamp.nanosec),
            500000000ll);
  EXPECT_TRUE(rig.log->contains(bus::LogLevel::Info, "played 3 frame(s), skipped 0"));
}

TEST(RgbdFolderCamera, LoopsAndPublishesItsPoseWithEveryFrame) {
  Frames f(2);
  Rig rig;
  auto& clouds = rig.collect<PointCloud2>("cloud");
  auto& poses = rig.collect<PoseStamped>("pose");
  bus::NodeOptions o;
  o.name = "camera";
  o.param("folder", f.dir.path.string()).param("rate_hz", 1.0).param("loop", true);
  o.param("pose_frame_id", std::string("base")).param("position_m", std::vector<double>{0.1, 0.2, 0.3});
  o.param("orientation_xyzw", std::vector<double>{0, 0, std::sqrt(0.5), std::sqrt(0.5)});
  rig.add("tomato_reasoning", "rgbd_folder_camera", o);
  rig.run_until(105.5);
  ASSERT_EQ(clouds.size(), 5u);
  EXPECT_FLOAT_EQ(first_z(*clouds[4]), 1.0f);  // frames 0 1 0 1 0
  EXPECT_FLOAT_EQ(first_z(*clouds[3]), 2.0f);
  ASSERT_EQ(poses.size(), 5u);
  EXPECT_EQ(poses[4]->header.frame_id, "base");
  EXPECT_EQ(poses[4]->header.stamp.sec, clouds[4]->header.stamp.sec);
  EXPECT_EQ(poses[4]->header.stamp.nanosec, clouds[4]->header.stamp.nanosec);
  EXPECT_DOUBLE_EQ(poses[4]->pose.position.y, 0.2);
  EXPECT_NEAR(poses[4]->pose.orientation.z, std::sqrt(0.5), 1e-12);
}

TEST(RgbdFolderCamera, SkipsABrokenFrameNamingItsFile) {
  Frames f(3);
  cv::imwrite(f.dir / "depth/000001.png", cv::Mat(3, 4, CV_8UC1, cv::Scalar(9)));  // 8-bit depth
  Rig rig;
  auto& clouds = rig.collect<PointCloud2>("cloud");
  bus::NodeOptions o;
  o.name = "camera";
  o.param("folder", f.dir.path.string());
  rig.add("tomato_reasoning", "rgbd_folder_camera", o);
  rig.run_until(110);
  ASSERT_EQ(clouds.size(), 2u);
  EXPECT_FLOAT_EQ(first_z(*clouds[1]), 3.0f);
  EXPECT_TRUE(rig.log->contains(bus::LogLevel::Warn,
                                "skipping frame 000001: depth image '" + f.dir / "depth/000001.png" + "' is 8-bit"));
  EXPECT_TRUE(rig.log->contains(bus::LogLevel::Info, "played 2 frame(s), skipped 1"));
}

TEST(RgbdFolderCamera, AFolderThatCannotBeOpenedStopsTheStart) {
  Frames f(0);
  const auto start = [&](const std::string& folder) {
    Rig rig;
    bus::NodeOptions o;
    o.name = "camera";
    o.param("folder", folder);
    rig.add("tomato_reasoning", "rgbd_folder_camera", o);
    try {
      rig.run_until(101);
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("started");
  };
  EXPECT_THAT(start(f.dir.path.string()), HasSubstr("'" + f.dir.path.string() + "' has no frames in rgb/"));
  EXPECT_THAT(start(f.dir / "missing"), HasSubstr("node '/camera' failed to configure: RGB-D folder '" +
                                                  f.dir / "missing" + "' is not a directory"));
  std::filesystem::remove(f.dir / "intrinsics.yaml");
  EXPECT_THAT(start(f.dir.path.string()), HasSubstr("intrinsics file '" + f.dir / "intrinsics.yaml" + "'"));
}

TEST(RgbdFolderCamera, ABadPoseOrNoFolderIsAParameterError) {
  Frames f(1);
  Rig rig;
  bus::NodeOptions o;
  o.name = "camera";
  EXPECT_THAT([&] { rig.add("tomato_reasoning", "rgbd_folder_camera", o); },
              ::testing::ThrowsMessage<bus::ParamError>(HasSubstr("parameter 'folder' is required")));
  o.param("folder", f.dir.path.string()).param("orientation_xyzw", std::vector<double>{0, 0, 0, 2});
  EXPECT_THAT([&] { rig.add("tomato_reasoning", "rgbd_folder_camera", o); },
              ::testing::ThrowsMessage<bus::ParamError>(HasSubstr("orientation_xyzw is not a unit quaternion")));
  o.param("orientation_xyzw", std::vector<double>{0, 0, 0, 1}).param("position_m", std::vector<double>{1, 2});
  EXPECT_THAT([&] { rig.add("tomato_reasoning", "rgbd_folder_camera", o); },
              ::testing::ThrowsMessage<bus::ParamError>(HasSubstr("position_m needs 3 numbers")));
}
