// SPDX-License-Identifier: Apache-2.0
// RGB-D frames on disk, in the layout RGB-D tools and data sets use (TUM,
// Redwood, Open3D): a folder with
//
//   intrinsics.yaml   width, height, fx, fy, cx, cy [px] and depth_scale
//                     (depth image units per metre: 1000 = millimetres)
//   rgb/NAME.png      8-bit colour (PNG or JPEG: NAME.jpg, NAME.jpeg)
//   depth/NAME.png    16-bit single-channel depth, registered to the colour
//                     image (0: no depth)
//
// read into the core's organised cloud (camera optical frame: x right, y
// down, z forward), and annotated debug images of a detection written back.
// OpenCV decodes and encodes the images; nothing here depends on the bus.
// Every error is an RgbdFileError naming the file and what is wrong with it.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include <tinyline/common/status.hpp>

#include "tomato_reasoning/cloud.hpp"
#include "tomato_reasoning/pipeline.hpp"

namespace tinyline::tomato_reasoning::io {

class RgbdFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A pinhole camera whose depth image is registered to its colour image.
struct CameraIntrinsics {
  int width = 0;                ///< [px]
  int height = 0;               ///< [px]
  double fx = 0;                ///< [px]
  double fy = 0;                ///< [px]
  double cx = 0;                ///< [px]
  double cy = 0;                ///< [px]
  double depth_scale = 1000.0;  ///< depth image units per metre (1000: mm; TUM uses 5000)
};

/// Whether the intrinsics can be used: InvalidArgument says what is wrong.
[[nodiscard]] common::Status check_intrinsics(const CameraIntrinsics& k);

/// Reads `path` (YAML: the fields of CameraIntrinsics by name).
[[nodiscard]] CameraIntrinsics read_intrinsics(const std::string& path);
/// Writes them to `path` (temporary file, then renamed onto it).
void write_intrinsics(const std::string& path, const CameraIntrinsics& k);

/// One frame of a folder: its name and its two image files.
struct FrameFiles {
  std::string name;    ///< the file name without extension ("000042")
  std::string colour;  ///< rgb/NAME.png (or .jpg, .jpeg)
  std::string depth;   ///< depth/NAME.png
};

/// A folder of RGB-D frames: its intrinsics and its frames in name order.
struct RgbdFolder {
  std::string path;
  CameraIntrinsics intrinsics;
  std::vector<FrameFiles> frames;
};

/// Reads FOLDER/intrinsics.yaml and lists FOLDER/rgb (a colour image without
/// its depth image is an error naming both). Reads no image.
[[nodiscard]] RgbdFolder open_folder(const std::string& folder);

/// A decoded frame: colour as OpenCV holds it (8-bit BGR) and raw depth (16 bit).
struct RgbdImages {
  cv::Mat bgr;    ///< CV_8UC3
  cv::Mat depth;  ///< CV_16UC1, units of 1 / depth_scale metres
};

/// Reads and checks one frame's images (sizes as the intrinsics say).
[[nodiscard]] RgbdImages read_images(const FrameFiles& f, const CameraIntrinsics& k);

/// The organised cloud of a frame: pixel (u, v) is point v * width + u at
/// z = depth / depth_scale, x = (u - cx) / fx * z, y = (v - cy) / fy * z;
/// NaN where the depth is 0.
[[nodiscard]] ColorCloud to_cloud(const RgbdImages& images, const CameraIntrinsics& k);

/// read_images + to_cloud.
[[nodiscard]] ColorCloud read_frame(const FrameFiles& f, const CameraIntrinsics& k);

/// Draws a detection on the colour image it came from: each tomato's
/// outline (green, the first to pick thicker), its expected pedicel
/// direction (yellow arrow), its cut point (magenta cross) and its pick
/// rank (1 = first). `result` in the camera's optical frame.
void draw_detections(cv::Mat& bgr, const PipelineResult& result, const CameraIntrinsics& k);

/// Encodes `image` by the path's extension (.png, .jpg, .jpeg) and writes it
/// to a temporary file beside `path` that is renamed onto it: `path` holds
/// the old image or the whole new one, never half of one.
void write_image(const std::string& path, const cv::Mat& image);

}  // namespace tinyline::tomato_reasoning::io
