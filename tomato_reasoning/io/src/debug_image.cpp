// SPDX-License-Identifier: Apache-2.0
#include <algorithm>
#include <cctype>
#include <filesystem>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "file_bytes.hpp"
#include "tomato_reasoning/io/rgbd_files.hpp"

namespace tinyline::tomato_reasoning::io {

namespace {

/// Pixel of a point in front of the camera (false behind it).
bool project(const Eigen::Vector3d& p, const CameraIntrinsics& k, cv::Point2d& uv) {
  if (!(p.z() > 1e-6) || !p.allFinite()) return false;
  uv = {k.fx * p.x() / p.z() + k.cx, k.fy * p.y() / p.z() + k.cy};
  return std::abs(uv.x) < 1e6 && std::abs(uv.y) < 1e6;
}

cv::Point px(const cv::Point2d& p) { return {cvRound(p.x), cvRound(p.y)}; }

const cv::Scalar kGreen(60, 220, 60), kYellow(0, 230, 255), kMagenta(255, 0, 255), kWhite(255, 255, 255);

void draw_tomato(cv::Mat& bgr, const Tomato& t, int rank, const CameraIntrinsics& k) {
  const Eigen::Vector3d& c = t.fit.sphere.centre;
  const double r = t.fit.sphere.radius_m;
  cv::Point2d centre, tip, base, cut;
  if (!project(c, k, centre)) return;
  // The outline: the sphere's radius at its centre's depth (Eq. 4.13's spheres as the camera sees them).
  const int radius_px = std::max(2, cvRound(k.fx * r / c.z()));
  cv::circle(bgr, px(centre), radius_px, kGreen, rank == 0 ? 3 : 1, cv::LINE_AA);
  const Eigen::Vector3d& dir = t.pedicel.expected_dir;
  if (project(c + r * dir, k, base) && project(c + (r + 0.04) * dir, k, tip))
    cv::arrowedLine(bgr, px(base), px(tip), kYellow, 2, cv::LINE_AA, 0, 0.3);
  if (project(t.cut.point, k, cut)) cv::drawMarker(bgr, px(cut), kMagenta, cv::MARKER_CROSS, 10, 2);
  if (rank >= 0)
    cv::putText(bgr, std::to_string(rank + 1), px(centre) + cv::Point(-6, 6), cv::FONT_HERSHEY_SIMPLEX, 0.6, kWhite, 2,
                cv::LINE_AA);
}

}  // namespace

void draw_detections(cv::Mat& bgr, const PipelineResult& result, const CameraIntrinsics& k) {
  for (const Tomato& t : result.tomatoes) draw_tomato(bgr, t, t.pick_rank, k);
  if (!result.status.ok())
    cv::putText(bgr, "no tomatoes (" + std::string(to_string(result.stage)) + ")", {10, 24}, cv::FONT_HERSHEY_SIMPLEX,
                0.6, kWhite, 1, cv::LINE_AA);
}

void write_image(const std::string& path, const cv::Mat& image) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  if (ext != ".png" && ext != ".jpg" && ext != ".jpeg")
    throw RgbdFileError("image '" + path + "': the name must end in .png, .jpg or .jpeg (the format it is written in)");
  std::vector<std::uint8_t> bytes;
  try {
    if (!cv::imencode(ext, image, bytes)) throw RgbdFileError("image '" + path + "' cannot be encoded as " + ext);
  } catch (const cv::Exception& e) {
    throw RgbdFileError("image '" + path + "' cannot be encoded as " + ext + ": " + e.what());
  }
  detail::write_atomically(path, "image", bytes.data(), bytes.size());
}

}  // namespace tinyline::tomato_reasoning::io
