// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/eval/frames_on_disk.hpp"

#include <cmath>
#include <filesystem>

#include <opencv2/core.hpp>

#include "tomato_reasoning/io/rgbd_files.hpp"

namespace tinyline::tomato_reasoning::eval {

namespace {

// The 8-bit BGR colour and the 16-bit depth [mm] images of an organised cloud.
io::RgbdImages images_of(const ColorCloud& c) {
  io::RgbdImages im{cv::Mat(c.height, c.width, CV_8UC3), cv::Mat(c.height, c.width, CV_16UC1)};
  for (int v = 0; v < c.height; ++v)
    for (int u = 0; u < c.width; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * static_cast<std::size_t>(c.width) + u;
      const Rgb& rgb = c.rgb[i];
      im.bgr.at<cv::Vec3b>(v, u) = cv::Vec3b(rgb[2], rgb[1], rgb[0]);
      const float z = c.xyz[i].z();
      im.depth.at<std::uint16_t>(v, u) =
          std::isfinite(z) && z > 0 && z < 65.0f ? static_cast<std::uint16_t>(std::lround(z * 1000.0f)) : 0;
    }
  return im;
}

}  // namespace

void round_trip_through_files(Scenario& s, const std::string& dir) {
  for (std::size_t v = 0; v < s.clouds.size(); ++v) {
    const sim::PinholeIntrinsics& K = s.frames[v].intrinsics;
    const io::CameraIntrinsics k{K.width, K.height, K.fx, K.fy, K.cx, K.cy, 1000.0};
    const std::filesystem::path folder =
        std::filesystem::path(dir) /
        (std::string(1, static_cast<char>(s.complexity)) + std::to_string(s.seed) + "_v" + std::to_string(v));
    std::filesystem::create_directories(folder / "rgb");
    std::filesystem::create_directories(folder / "depth");
    const io::RgbdImages im = images_of(s.clouds[v]);
    io::write_image((folder / "rgb" / "000000.png").string(), im.bgr);
    io::write_image((folder / "depth" / "000000.png").string(), im.depth);
    io::write_intrinsics((folder / "intrinsics.yaml").string(), k);
    const io::RgbdFolder f = io::open_folder(folder.string());
    s.clouds[v] = io::read_frame(f.frames.front(), f.intrinsics);
  }
}

}  // namespace tinyline::tomato_reasoning::eval
