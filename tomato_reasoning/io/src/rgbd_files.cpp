// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/io/rgbd_files.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <limits>
#include <sstream>
#include <type_traits>

#include <opencv2/imgcodecs.hpp>
#include <yaml-cpp/yaml.h>

#include "file_bytes.hpp"

namespace tinyline::tomato_reasoning::io {

namespace fs = std::filesystem;

namespace {

constexpr std::uint64_t kMaxIntrinsicsBytes = 64 * 1024;
constexpr std::uint64_t kMaxImageBytes = 256ull * 1024 * 1024;
constexpr int kMaxSidePx = 16384;

bool is_colour_extension(const fs::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return e == ".png" || e == ".jpg" || e == ".jpeg";
}

template <class T>
T field(const YAML::Node& doc, const char* key, const std::string& path) {
  const YAML::Node v = doc[key];
  if (!v) throw RgbdFileError("intrinsics file '" + path + "' has no '" + key + "'");
  try {
    return v.as<T>();
  } catch (const YAML::Exception&) {
    throw RgbdFileError("intrinsics file '" + path + "': '" + key + "' is not a number" +
                        (std::is_integral_v<T> ? " of whole pixels" : ""));
  }
}

std::string size_text(int w, int h) { return std::to_string(w) + " x " + std::to_string(h); }

cv::Mat decode(const std::string& path, const char* what, int flags) {
  const std::vector<std::uint8_t> bytes = detail::read_bytes(path, what, kMaxImageBytes);
  cv::Mat m;
  try {
    m = cv::imdecode(bytes, flags);
  } catch (const cv::Exception& e) {
    throw RgbdFileError(std::string(what) + " '" + path + "' cannot be decoded: " + e.what());
  }
  if (m.empty())
    throw RgbdFileError(std::string(what) + " '" + path + "' is not an image OpenCV can decode (PNG or JPEG)");
  return m;
}

}  // namespace

std::string check_intrinsics(const CameraIntrinsics& k) {
  if (k.width < 1 || k.height < 1 || k.width > kMaxSidePx || k.height > kMaxSidePx)
    return "width and height must be 1-" + std::to_string(kMaxSidePx) + " px (are " + size_text(k.width, k.height) +
           ")";
  if (!(std::isfinite(k.fx) && k.fx > 0) || !(std::isfinite(k.fy) && k.fy > 0))
    return "fx and fy must be finite and > 0";
  if (!std::isfinite(k.cx) || !std::isfinite(k.cy)) return "cx and cy must be finite";
  if (!(std::isfinite(k.depth_scale) && k.depth_scale > 0))
    return "depth_scale must be finite and > 0 (depth image units per metre, 1000 for millimetres)";
  return {};
}

CameraIntrinsics read_intrinsics(const std::string& path) {
  const auto bytes = detail::read_bytes(path, "intrinsics file", kMaxIntrinsicsBytes);
  YAML::Node doc;
  try {
    doc = YAML::Load(std::string(bytes.begin(), bytes.end()));
  } catch (const YAML::Exception& e) {
    throw RgbdFileError("intrinsics file '" + path + "' is not YAML: " + e.what());
  }
  if (!doc.IsMap())
    throw RgbdFileError("intrinsics file '" + path + "' is not a YAML map of width, height, fx, fy, cx, cy");
  CameraIntrinsics k;
  k.width = field<int>(doc, "width", path);
  k.height = field<int>(doc, "height", path);
  k.fx = field<double>(doc, "fx", path);
  k.fy = field<double>(doc, "fy", path);
  k.cx = field<double>(doc, "cx", path);
  k.cy = field<double>(doc, "cy", path);
  if (doc["depth_scale"]) k.depth_scale = field<double>(doc, "depth_scale", path);
  if (const std::string bad = check_intrinsics(k); !bad.empty())
    throw RgbdFileError("intrinsics file '" + path + "': " + bad);
  return k;
}

void write_intrinsics(const std::string& path, const CameraIntrinsics& k) {
  if (const std::string bad = check_intrinsics(k); !bad.empty())
    throw RgbdFileError("intrinsics for '" + path + "': " + bad);
  std::ostringstream s;
  s.precision(std::numeric_limits<double>::max_digits10);
  s << "# pinhole camera, depth registered to colour\nwidth: " << k.width << "\nheight: " << k.height
    << "\nfx: " << k.fx << "\nfy: " << k.fy << "\ncx: " << k.cx << "\ncy: " << k.cy
    << "\ndepth_scale: " << k.depth_scale << "  # depth image units per metre\n";
  const std::string text = s.str();
  detail::write_atomically(path, "intrinsics file", text.data(), text.size());
}

RgbdFolder open_folder(const std::string& folder) {
  RgbdFolder f;
  f.path = folder;
  const fs::path root(folder);
  std::error_code ec;
  if (!fs::is_directory(root, ec)) throw RgbdFileError("RGB-D folder '" + folder + "' is not a directory");
  f.intrinsics = read_intrinsics((root / "intrinsics.yaml").string());
  const fs::path rgb = root / "rgb", depth = root / "depth";
  if (!fs::is_directory(rgb, ec)) throw RgbdFileError("RGB-D folder '" + folder + "' has no rgb/ directory");
  for (const auto& e : fs::directory_iterator(rgb, ec)) {
    if (!is_colour_extension(e.path())) continue;
    FrameFiles ff;
    ff.name = e.path().stem().string();
    ff.colour = e.path().string();
    ff.depth = (depth / (ff.name + ".png")).string();
    if (!fs::exists(ff.depth, ec))
      throw RgbdFileError("colour image '" + ff.colour + "' has no depth image '" + ff.depth + "'");
    f.frames.push_back(std::move(ff));
  }
  if (ec) throw RgbdFileError("RGB-D folder '" + folder + "': cannot list rgb/: " + ec.message());
  std::sort(f.frames.begin(), f.frames.end(), [](const FrameFiles& a, const FrameFiles& b) { return a.name < b.name; });
  for (std::size_t i = 1; i < f.frames.size(); ++i)
    if (f.frames[i].name == f.frames[i - 1].name)
      throw RgbdFileError("frame '" + f.frames[i].name + "' has two colour images: '" + f.frames[i - 1].colour +
                          "' and '" + f.frames[i].colour + "'");
  return f;
}

RgbdImages read_images(const FrameFiles& f, const CameraIntrinsics& k) {
  RgbdImages im;
  im.bgr = decode(f.colour, "colour image", cv::IMREAD_COLOR);
  im.depth = decode(f.depth, "depth image", cv::IMREAD_UNCHANGED);
  if (im.depth.depth() != CV_16U || im.depth.channels() != 1)
    throw RgbdFileError("depth image '" + f.depth + "' is " + std::to_string(8 * im.depth.elemSize1()) + "-bit with " +
                        std::to_string(im.depth.channels()) +
                        " channel(s); depth must be a 16-bit single-channel PNG (units of 1/depth_scale m)");
  if (im.bgr.cols != k.width || im.bgr.rows != k.height)
    throw RgbdFileError("colour image '" + f.colour + "' is " + size_text(im.bgr.cols, im.bgr.rows) +
                        " px but the intrinsics say " + size_text(k.width, k.height));
  if (im.depth.cols != k.width || im.depth.rows != k.height)
    throw RgbdFileError("depth image '" + f.depth + "' is " + size_text(im.depth.cols, im.depth.rows) +
                        " px but the intrinsics say " + size_text(k.width, k.height));
  return im;
}

ColorCloud to_cloud(const RgbdImages& im, const CameraIntrinsics& k) {
  // read_images checks files; this checks images a caller decoded itself.
  if (im.bgr.type() != CV_8UC3 || im.depth.type() != CV_16UC1 || im.bgr.size() != im.depth.size())
    throw RgbdFileError("RGB-D frame: colour must be 8-bit BGR and depth 16-bit single-channel, of one size (are " +
                        size_text(im.bgr.cols, im.bgr.rows) + " and " + size_text(im.depth.cols, im.depth.rows) + ")");
  ColorCloud c;
  c.width = im.bgr.cols;
  c.height = im.bgr.rows;
  c.xyz.resize(std::size_t(c.width) * std::size_t(c.height));
  c.rgb.resize(c.xyz.size());
  constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
  for (int v = 0; v < c.height; ++v) {
    const auto* d = im.depth.ptr<std::uint16_t>(v);
    const auto* p = im.bgr.ptr<cv::Vec3b>(v);
    const float yn = static_cast<float>((v - k.cy) / k.fy);
    for (int u = 0; u < c.width; ++u) {
      const std::size_t i = std::size_t(v) * std::size_t(c.width) + std::size_t(u);
      c.rgb[i] = {p[u][2], p[u][1], p[u][0]};
      if (d[u] == 0) {
        c.xyz[i] = {kNaN, kNaN, kNaN};
        continue;
      }
      const float z = static_cast<float>(d[u] / k.depth_scale);
      c.xyz[i] = {static_cast<float>((u - k.cx) / k.fx) * z, yn * z, z};
    }
  }
  return c;
}

ColorCloud read_frame(const FrameFiles& f, const CameraIntrinsics& k) { return to_cloud(read_images(f, k), k); }

}  // namespace tinyline::tomato_reasoning::io
