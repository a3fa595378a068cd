// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/io/rgbd_files.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <limits>
#include <optional>
#include <sstream>

#include <opencv2/imgcodecs.hpp>
#include <tinyline/common/yaml_fields.hpp>
#include <yaml-cpp/yaml.h>

#include "file_bytes.hpp"

namespace tinyline::tomato_reasoning::io {

namespace fs = std::filesystem;

namespace {

constexpr std::uint64_t kMaxIntrinsicsBytes = 64 * 1024;
constexpr std::uint64_t kMaxImageBytes = 256ull * 1024 * 1024;
constexpr int kMaxSidePx = 16384;
// A frame's colour, depth and cloud take about 30 bytes a pixel: 16.8 Mpx (4096 x 4096) is about 0.5 GB.
constexpr std::int64_t kMaxPixels = 4096 * 4096;
constexpr double kMinFocalPx = 1.0, kMaxFocalPx = 1e6;
constexpr double kMinDepthScale = 1e-3, kMaxDepthScale = 1e6;

std::string fmt_number(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

bool is_colour_extension(const fs::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return e == ".png" || e == ".jpg" || e == ".jpeg";
}

using Fields = common::YamlFields<RgbdFileError>;

std::string size_text(int w, int h) { return std::to_string(w) + " x " + std::to_string(h); }

// Big-endian integers of an image header.
std::uint32_t be16(const std::vector<std::uint8_t>& b, std::size_t i) { return (b[i] << 8) | b[i + 1]; }
std::uint32_t be32(const std::vector<std::uint8_t>& b, std::size_t i) { return (be16(b, i) << 16) | be16(b, i + 2); }

struct ImageHeader {
  std::uint32_t width = 0, height = 0;
  bool whole = false;  ///< the end-of-image mark is there (a cut file decodes grey with only a warning)
};

bool starts_with(const std::vector<std::uint8_t>& b, std::initializer_list<std::uint8_t> head) {
  return b.size() >= head.size() && std::equal(head.begin(), head.end(), b.begin());
}

bool ends_with(const std::vector<std::uint8_t>& b, std::initializer_list<std::uint8_t> tail) {
  return b.size() >= tail.size() && std::equal(tail.begin(), tail.end(), b.end() - std::ptrdiff_t(tail.size()));
}

// PNG: the IHDR chunk first, the IEND chunk last.
std::optional<ImageHeader> png_header(const std::vector<std::uint8_t>& b) {
  if (!starts_with(b, {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A}) || b.size() < 24) return std::nullopt;
  if (!std::equal(b.begin() + 12, b.begin() + 16, "IHDR")) return std::nullopt;
  return ImageHeader{be32(b, 16), be32(b, 20), ends_with(b, {0, 0, 0, 0, 'I', 'E', 'N', 'D', 0xAE, 0x42, 0x60, 0x82})};
}

// JPEG: the size in the first start-of-frame segment, the EOI mark last.
std::optional<ImageHeader> jpeg_header(const std::vector<std::uint8_t>& b) {
  if (!starts_with(b, {0xFF, 0xD8})) return std::nullopt;
  std::size_t i = 2;
  while (i + 4 <= b.size() && b[i] == 0xFF) {
    const std::uint8_t m = b[i + 1];
    if (m == 0xFF || m == 0x01 || (m >= 0xD0 && m <= 0xD7)) {  // fill byte, markers without a length
      i += m == 0xFF ? 1 : 2;
      continue;
    }
    const bool sof = m >= 0xC0 && m <= 0xCF && m != 0xC4 && m != 0xC8 && m != 0xCC;
    if (sof && i + 9 <= b.size()) return ImageHeader{be16(b, i + 7), be16(b, i + 5), ends_with(b, {0xFF, 0xD9})};
    if (sof || m == 0xDA) return std::nullopt;  // cut in its header, or image data before any size
    i += 2 + be16(b, i + 2);
  }
  return std::nullopt;
}

// The image's size from its header, checked against the intrinsics before it
// is decoded: a huge image is refused before it takes its memory.
void check_header(const std::vector<std::uint8_t>& bytes, const std::string& path, const char* what,
                  const CameraIntrinsics& k) {
  auto h = png_header(bytes);
  if (!h) h = jpeg_header(bytes);
  const std::string name = std::string(what) + " '" + path + "'";
  if (!h) throw RgbdFileError(name + " is not an image OpenCV can decode (PNG or JPEG): no PNG or JPEG header");
  if (h->width != std::uint32_t(k.width) || h->height != std::uint32_t(k.height)) {
    throw RgbdFileError(name + " is " + std::to_string(h->width) + " x " + std::to_string(h->height) +
                        " px but the intrinsics say " + size_text(k.width, k.height));
  }
  if (!h->whole) throw RgbdFileError(name + " is cut short: it has no end-of-image mark (a truncated file)");
}

cv::Mat decode(const std::string& path, const char* what, int flags, const CameraIntrinsics& k) {
  const std::vector<std::uint8_t> bytes = detail::read_bytes(path, what, kMaxImageBytes);
  check_header(bytes, path, what, k);
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

// A whole number of pixels.
int pixels(const Fields& f, const YAML::Node& doc, const char* key) {
  const double v = f.number(doc, "", key);
  if (v != std::floor(v) || std::abs(v) > 1e9) f.fail(doc[key], key, "is not a number of whole pixels");
  return static_cast<int>(v);
}

}  // namespace

common::Status check_intrinsics(const CameraIntrinsics& k) {
  if (k.width < 1 || k.height < 1 || k.width > kMaxSidePx || k.height > kMaxSidePx)
    return common::Status::invalid("width and height must be 1-" + std::to_string(kMaxSidePx) + " px (are " +
                                   size_text(k.width, k.height) + ")");
  if (std::int64_t(k.width) * k.height > kMaxPixels)
    return common::Status::invalid("width x height must be at most " + std::to_string(kMaxPixels) + " px (is " +
                                   size_text(k.width, k.height) + ")");
  if (!(k.fx >= kMinFocalPx && k.fx <= kMaxFocalPx) || !(k.fy >= kMinFocalPx && k.fy <= kMaxFocalPx))
    return common::Status::invalid("fx and fy must be finite, " + fmt_number(kMinFocalPx) + "-" +
                                   fmt_number(kMaxFocalPx) + " px");
  if (!(std::abs(k.cx) <= 2.0 * k.width) || !(std::abs(k.cy) <= 2.0 * k.height))
    return common::Status::invalid("cx and cy must be finite and within twice the image size of its corner");
  if (!(k.depth_scale >= kMinDepthScale && k.depth_scale <= kMaxDepthScale))
    return common::Status::invalid("depth_scale must be finite and > 0, " + fmt_number(kMinDepthScale) + "-" +
                                   fmt_number(kMaxDepthScale) + " (depth image units per metre, 1000 for millimetres)");
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
  // Unknown and repeated keys are errors: `depth-scale: 5000` would silently be 1000.
  const Fields f(path);
  f.only_keys(doc, "", {"width", "height", "fx", "fy", "cx", "cy", "depth_scale"});
  CameraIntrinsics k;
  k.width = pixels(f, doc, "width");
  k.height = pixels(f, doc, "height");
  k.fx = f.number(doc, "", "fx");
  k.fy = f.number(doc, "", "fy");
  k.cx = f.number(doc, "", "cx");
  k.cy = f.number(doc, "", "cy");
  k.depth_scale = f.number_or(doc, "", "depth_scale", k.depth_scale);
  if (const common::Status bad = check_intrinsics(k); !bad.ok())
    throw RgbdFileError("intrinsics file '" + path + "': " + bad.message);
  return k;
}

void write_intrinsics(const std::string& path, const CameraIntrinsics& k) {
  if (const common::Status bad = check_intrinsics(k); !bad.ok())
    throw RgbdFileError("intrinsics for '" + path + "': " + bad.message);
  std::ostringstream s;
  s.precision(std::numeric_limits<double>::max_digits10);
  s << "# pinhole camera, depth registered to colour\nwidth: " << k.width << "\nheight: " << k.height
    << "\nfx: " << k.fx << "\nfy: " << k.fy << "\ncx: " << k.cx << "\ncy: " << k.cy
    << "\ndepth_scale: " << k.depth_scale << "  # depth image units per metre\n";
  const std::string text = s.str();
  detail::write_atomically(path, "intrinsics file", text.data(), text.size());
}

namespace {

// A depth image that cannot be looked at (a symbolic link loop, no
// permission) says why; only a missing one "has no depth image".
void check_depth_exists(const FrameFiles& ff) {
  std::error_code ec;
  const fs::file_status st = fs::status(ff.depth, ec);
  if (ec && ec != std::errc::no_such_file_or_directory)
    throw RgbdFileError("depth image '" + ff.depth + "' of colour image '" + ff.colour + "': " + ec.message());
  if (!fs::exists(st)) throw RgbdFileError("colour image '" + ff.colour + "' has no depth image '" + ff.depth + "'");
}

}  // namespace

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
    check_depth_exists(ff);
    f.frames.push_back(std::move(ff));
  }
  if (ec) throw RgbdFileError("RGB-D folder '" + folder + "': cannot list rgb/: " + ec.message());
  if (f.frames.empty()) throw RgbdFileError("RGB-D folder '" + folder + "' has no frames in rgb/");
  std::sort(f.frames.begin(), f.frames.end(), [](const FrameFiles& a, const FrameFiles& b) { return a.name < b.name; });
  for (std::size_t i = 1; i < f.frames.size(); ++i)
    if (f.frames[i].name == f.frames[i - 1].name)
      throw RgbdFileError("frame '" + f.frames[i].name + "' has two colour images: '" + f.frames[i - 1].colour +
                          "' and '" + f.frames[i].colour + "'");
  return f;
}

RgbdImages read_images(const FrameFiles& f, const CameraIntrinsics& k) {
  RgbdImages im;
  im.bgr = decode(f.colour, "colour image", cv::IMREAD_COLOR, k);
  im.depth = decode(f.depth, "depth image", cv::IMREAD_UNCHANGED, k);
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
