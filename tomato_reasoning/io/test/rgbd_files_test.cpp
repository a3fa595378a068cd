// SPDX-License-Identifier: Apache-2.0
// RGB-D frames from files: the folder layout read into the organised cloud,
// bad input refused with the file named, debug images written whole.
#include <sys/stat.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "tomato_reasoning/io/rgbd_files.hpp"

namespace io = tinyline::tomato_reasoning::io;
namespace fs = std::filesystem;
using ::testing::AllOf;
using ::testing::HasSubstr;

namespace {

struct Folder {
  fs::path root;
  io::CameraIntrinsics k;
  Folder() {
    char tmpl[] = "/tmp/tinyline_rgbd_XXXXXX";
    root = ::mkdtemp(tmpl);
    fs::create_directories(root / "rgb");
    fs::create_directories(root / "depth");
    k.width = 8;
    k.height = 6;
    k.fx = 10;
    k.fy = 12;
    k.cx = 3.5;
    k.cy = 2.5;
    io::write_intrinsics((root / "intrinsics.yaml").string(), k);
  }
  ~Folder() { fs::remove_all(root); }
  std::string rgb(const std::string& n) const { return (root / "rgb" / n).string(); }
  std::string depth(const std::string& n) const { return (root / "depth" / n).string(); }
  /// Colour (r = 10 u, g = 20 v, b = 7) and depth (1000 + 100 u + v mm, 0 at (1, 1)).
  void add_frame(const std::string& name, int w = 8, int h = 6, int depth_type = CV_16UC1) const {
    cv::Mat bgr(h, w, CV_8UC3), d(h, w, depth_type);
    for (int v = 0; v < h; ++v)
      for (int u = 0; u < w; ++u) {
        bgr.at<cv::Vec3b>(v, u) = {7, std::uint8_t(20 * v), std::uint8_t(10 * u)};
        if (depth_type == CV_16UC1)
          d.at<std::uint16_t>(v, u) = std::uint16_t(u == 1 && v == 1 ? 0 : 1000 + 100 * u + v);
        else
          d.at<std::uint8_t>(v, u) = std::uint8_t(100 + u);
      }
    ASSERT_TRUE(cv::imwrite(rgb(name + ".png"), bgr));
    ASSERT_TRUE(cv::imwrite(depth(name + ".png"), d));
  }
  void write(const std::string& path, const std::string& text) const { std::ofstream(path) << text; }
};

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const io::RgbdFileError& e) {
    return e.what();
  }
  return "no error";
}

}  // namespace

TEST(RgbdFiles, FolderFramesBecomeTheOrganisedCloud) {
  Folder f;
  f.add_frame("000001");
  f.add_frame("000000");
  const io::RgbdFolder folder = io::open_folder(f.root.string());
  EXPECT_EQ(folder.intrinsics.fx, 10);
  EXPECT_EQ(folder.intrinsics.depth_scale, 1000);
  ASSERT_EQ(folder.frames.size(), 2u);
  EXPECT_EQ(folder.frames[0].name, "000000");  // name order
  EXPECT_EQ(folder.frames[1].depth, f.depth("000001.png"));
  const auto c = io::read_frame(folder.frames[0], folder.intrinsics);
  ASSERT_EQ(c.width, 8);
  ASSERT_EQ(c.height, 6);
  ASSERT_EQ(c.size(), 48u);
  // Pixel (u, v) = (5, 3): z = 1.503 m, x = (5 - 3.5) / 10 z, y = (3 - 2.5) / 12 z.
  const std::size_t i = 3 * 8 + 5;
  EXPECT_FLOAT_EQ(c.xyz[i].z(), 1.503f);
  EXPECT_FLOAT_EQ(c.xyz[i].x(), 0.15f * 1.503f);
  EXPECT_FLOAT_EQ(c.xyz[i].y(), float(0.5 / 12) * 1.503f);
  EXPECT_EQ(c.rgb[i], (tinyline::tomato_reasoning::Rgb{50, 60, 7}));  // RGB order, not OpenCV's BGR
  EXPECT_FALSE(c.finite(1 * 8 + 1));                                  // depth 0: no point
  EXPECT_TRUE(c.finite(0));
}

TEST(RgbdFiles, DepthScaleAndJpegColourAreHonoured) {
  Folder f;
  f.add_frame("a");
  cv::Mat bgr = cv::imread(f.rgb("a.png"));
  fs::remove(f.rgb("a.png"));
  ASSERT_TRUE(cv::imwrite(f.rgb("a.jpg"), bgr));
  f.k.depth_scale = 5000;  // TUM's convention: 1/5 mm
  io::write_intrinsics((f.root / "intrinsics.yaml").string(), f.k);
  const auto folder = io::open_folder(f.root.string());
  ASSERT_EQ(folder.frames.size(), 1u);
  EXPECT_EQ(folder.frames[0].colour, f.rgb("a.jpg"));
  const auto c = io::read_frame(folder.frames[0], folder.intrinsics);
  EXPECT_FLOAT_EQ(c.xyz[0].z(), 1000.0f / 5000.0f);
}

TEST(RgbdFiles, MissingFilesAreNamed) {
  Folder f;
  EXPECT_THAT(error_of([&] { (void)io::open_folder((f.root / "nope").string()); }), HasSubstr("is not a directory"));
  f.add_frame("000000");
  fs::remove(f.depth("000000.png"));
  EXPECT_THAT(error_of([&] { (void)io::open_folder(f.root.string()); }),
              AllOf(HasSubstr(f.rgb("000000.png")), HasSubstr("has no depth image '" + f.depth("000000.png") + "'")));
  fs::remove(f.root / "intrinsics.yaml");
  EXPECT_THAT(
      error_of([&] { (void)io::open_folder(f.root.string()); }),
      AllOf(HasSubstr("intrinsics file '" + (f.root / "intrinsics.yaml").string() + "'"), HasSubstr("No such file")));
}

TEST(RgbdFiles, BadIntrinsicsAreRefusedWithTheReason) {
  Folder f;
  const std::string p = (f.root / "intrinsics.yaml").string();
  f.write(p, "width: 8\nheight: 6\nfx: .nan\nfy: 12\ncx: 3.5\ncy: 2.5\n");
  EXPECT_THAT(error_of([&] { (void)io::read_intrinsics(p); }), AllOf(HasSubstr(p + ":3: field 'fx': must be finite")));
  f.write(p, "width: 8\nheight: 6\nfx: 10\nfy: 12\ncx: 3.5\n");
  EXPECT_THAT(error_of([&] { (void)io::read_intrinsics(p); }), HasSubstr("field 'cy': missing"));
  f.write(p, "width: 8.5\nheight: 6\nfx: 10\nfy: 12\ncx: 3.5\ncy: 1\n");
  EXPECT_THAT(error_of([&] { (void)io::read_intrinsics(p); }), HasSubstr("'width': is not a number of whole pixels"));
  f.write(p, "width: 8\nheight: 6\nfx: 10\nfy: 12\ncx: 3.5\ncy: 1\ndepth_scale: 0\n");
  EXPECT_THAT(error_of([&] { (void)io::read_intrinsics(p); }), HasSubstr("depth_scale must be finite and > 0"));
  f.write(p, "[1, 2");
  EXPECT_THAT(error_of([&] { (void)io::read_intrinsics(p); }), HasSubstr("is not YAML"));
}

TEST(RgbdFiles, BadImagesAreRefusedNamingTheFile) {
  Folder f;
  const io::FrameFiles frame{"x", f.rgb("x.png"), f.depth("x.png")};
  f.add_frame("x", 8, 6, CV_8UC1);  // an 8-bit depth image (a preview, not depth)
  EXPECT_THAT(error_of([&] { (void)io::read_frame(frame, f.k); }),
              AllOf(HasSubstr(f.depth("x.png")), HasSubstr("is 8-bit"), HasSubstr("16-bit single-channel")));
  f.add_frame("x", 9, 6);  // both 9 px wide, the intrinsics say 8
  EXPECT_THAT(error_of([&] { (void)io::read_frame(frame, f.k); }),
              AllOf(HasSubstr("colour image '" + f.rgb("x.png") + "' is 9 x 6 px but the intrinsics say 8 x 6")));
  f.add_frame("x");
  cv::Mat small(5, 8, CV_16UC1, cv::Scalar(1000));
  ASSERT_TRUE(cv::imwrite(f.depth("x.png"), small));  // depth of another size than colour
  EXPECT_THAT(error_of([&] { (void)io::read_frame(frame, f.k); }),
              HasSubstr("depth image '" + f.depth("x.png") + "' is 8 x 5 px but the intrinsics say 8 x 6"));
  f.write(f.depth("x.png"), "\x89PNG\r\n\x1a\n truncated");
  EXPECT_THAT(error_of([&] { (void)io::read_frame(frame, f.k); }),
              AllOf(HasSubstr(f.depth("x.png")), HasSubstr("not an image OpenCV can decode")));
}

TEST(RgbdFiles, ImagesOfTwoSizesOrTheWrongTypesMakeNoCloud) {
  io::CameraIntrinsics k;
  k.width = 4, k.height = 3, k.fx = k.fy = 5, k.cx = 1.5, k.cy = 1;
  io::RgbdImages im{cv::Mat(3, 4, CV_8UC3), cv::Mat(2, 4, CV_16UC1)};
  EXPECT_THAT(error_of([&] { (void)io::to_cloud(im, k); }), HasSubstr("(are 4 x 3 and 4 x 2)"));
  im.depth = cv::Mat(3, 4, CV_32FC1);
  EXPECT_THAT(error_of([&] { (void)io::to_cloud(im, k); }), HasSubstr("depth 16-bit single-channel"));
}

TEST(RgbdFiles, AFifoIsRefusedNotWaitedOn) {
  Folder f;
  f.add_frame("x");
  fs::remove(f.rgb("x.png"));
  ASSERT_EQ(::mkfifo(f.rgb("x.png").c_str(), 0600), 0);
  const io::FrameFiles frame{"x", f.rgb("x.png"), f.depth("x.png")};
  EXPECT_THAT(error_of([&] { (void)io::read_frame(frame, f.k); }),
              HasSubstr("colour image '" + f.rgb("x.png") + "' is a FIFO, not a regular file"));
}

TEST(RgbdFiles, DebugImagesAreDrawnAndWrittenWhole) {
  Folder f;
  io::CameraIntrinsics k;
  k.width = 160, k.height = 120, k.fx = k.fy = 100, k.cx = 79.5, k.cy = 59.5;
  tinyline::tomato_reasoning::PipelineResult r;
  r.status = {};
  r.tomatoes.resize(1);
  r.tomatoes[0].fit.sphere.centre = {0, 0, 0.5};
  r.tomatoes[0].fit.sphere.radius_m = 0.1;  // 20 px at 0.5 m
  r.tomatoes[0].pedicel.expected_dir = {0, -1, 0};
  r.tomatoes[0].cut.point = {0, -0.12, 0.5};
  r.tomatoes[0].pick_rank = 0;
  cv::Mat img(120, 160, CV_8UC3, cv::Scalar(0, 0, 0));
  io::draw_detections(img, r, k);
  EXPECT_GT(img.at<cv::Vec3b>(60, 100)[1], 100);  // the outline, 20 px right of the centre, in green
  EXPECT_EQ(img.at<cv::Vec3b>(5, 5), cv::Vec3b(0, 0, 0));
  EXPECT_GT(cv::countNonZero(img.reshape(1) > 0), 100);

  const std::string out = f.rgb("debug.png");
  io::write_image(out, img);
  EXPECT_FALSE(fs::exists(out + ".part"));
  const cv::Mat back = cv::imread(out);
  ASSERT_FALSE(back.empty());
  EXPECT_EQ(cv::norm(back, img, cv::NORM_INF), 0.0);
  // A writer that cannot finish leaves the old image as it was.
  fs::create_directory(out + ".part");
  EXPECT_THAT(error_of([&] { io::write_image(out, cv::Mat(4, 4, CV_8UC3, cv::Scalar(255, 0, 0))); }),
              HasSubstr(out + ".part"));
  EXPECT_EQ(cv::norm(cv::imread(out), img, cv::NORM_INF), 0.0);
  EXPECT_THAT(error_of([&] { io::write_image((f.root / "rgb").string(), img); }), HasSubstr(".png, .jpg or .jpeg"));
  EXPECT_THAT(error_of([&] { io::write_image((f.root / "rgb.png").string() + "/x.png", img); }),
              HasSubstr("x.png.part"));
}

// Regression: unknown and repeated keys were ignored (`depth-scale: 5000`
// silently used 1000; of two fx the first won), and absurd numbers accepted.
TEST(RgbdFiles, UnknownRepeatedAndAbsurdIntrinsicsAreRefused) {
  Folder f;
  const std::string p = (f.root / "intrinsics.yaml").string();
  const std::string good = "width: 8\nheight: 6\nfx: 10\nfy: 12\ncx: 3.5\ncy: 2.5\n";
  f.write(p, good + "depth-scale: 5000\n");
  EXPECT_THAT(error_of([&] { (void)io::read_intrinsics(p); }),
              AllOf(HasSubstr(p + ":7: field 'depth-scale': unknown key"), HasSubstr("depth_scale")));
  f.write(p, good + "fx: 11\n");
  EXPECT_THAT(error_of([&] { (void)io::read_intrinsics(p); }), HasSubstr(p + ":7: field 'fx': given twice"));
  f.write(p, "width: 8\nheight: 6\nfx: 1e-300\nfy: 12\ncx: 3.5\ncy: 2.5\n");
  EXPECT_THAT(error_of([&] { (void)io::read_intrinsics(p); }), HasSubstr("fx and fy must be finite, 1-1e+06 px"));
  f.write(p, "width: 8\nheight: 6\nfx: 10\nfy: 12\ncx: 1e300\ncy: 2.5\n");
  EXPECT_THAT(error_of([&] { (void)io::read_intrinsics(p); }), HasSubstr("cx and cy must be finite and within"));
  f.write(p, "width: 16384\nheight: 16384\nfx: 10\nfy: 12\ncx: 3.5\ncy: 2.5\n");
  EXPECT_THAT(error_of([&] { (void)io::read_intrinsics(p); }), HasSubstr("width x height must be at most 16777216 px"));
}

// Regression: a JPEG cut at 80 % decoded grey with only a decoder warning
// (and changed the pick order); a cut PNG is refused the same way.
TEST(RgbdFiles, ATruncatedImageIsRefusedNotDecodedGrey) {
  Folder f;
  f.add_frame("x");
  cv::Mat bgr(6, 8, CV_8UC3, cv::Scalar(10, 200, 30));
  std::vector<std::uint8_t> jpg;
  ASSERT_TRUE(cv::imencode(".jpg", bgr, jpg));
  fs::remove(f.rgb("x.png"));
  f.write(f.rgb("x.jpg"), std::string(jpg.begin(), jpg.begin() + std::ptrdiff_t(jpg.size() * 8 / 10)));
  const io::FrameFiles cut_jpeg{"x", f.rgb("x.jpg"), f.depth("x.png")};
  EXPECT_THAT(error_of([&] { (void)io::read_frame(cut_jpeg, f.k); }),
              HasSubstr("colour image '" + f.rgb("x.jpg") + "' is cut short"));
  f.write(f.rgb("x.jpg"), std::string(jpg.begin(), jpg.end()));
  EXPECT_EQ(error_of([&] { (void)io::read_frame(cut_jpeg, f.k); }), "no error");
  std::ifstream in(f.depth("x.png"), std::ios::binary);
  const std::string png((std::istreambuf_iterator<char>(in)), {});
  f.write(f.depth("x.png"), png.substr(0, png.size() * 8 / 10));
  EXPECT_THAT(error_of([&] { (void)io::read_frame(cut_jpeg, f.k); }),
              HasSubstr("depth image '" + f.depth("x.png") + "' is cut short"));
}

// Regression: a 16384 x 16384 pair of about 1 MB took 5.3 GB to decode
// before its size was checked: the header's size is checked first.
TEST(RgbdFiles, AnImageLargerThanItsIntrinsicsIsRefusedBeforeDecoding) {
  Folder f;
  f.add_frame("x");
  std::ifstream in(f.depth("x.png"), std::ios::binary);
  std::string png((std::istreambuf_iterator<char>(in)), {});
  png[16] = png[20] = 0, png[17] = png[21] = 0, png[18] = png[22] = 0x40, png[19] = png[23] = 0;  // 16384 x 16384
  f.write(f.depth("x.png"), png);
  const io::FrameFiles frame{"x", f.rgb("x.png"), f.depth("x.png")};
  EXPECT_THAT(error_of([&] { (void)io::read_frame(frame, f.k); }),
              HasSubstr("depth image '" + f.depth("x.png") + "' is 16384 x 16384 px but the intrinsics say 8 x 6"));
}

// Regression: a depth image behind a symbolic link loop read as "has no
// depth image"; an empty rgb/ was a folder of no frames (exit 0).
TEST(RgbdFiles, ALinkLoopAndAnEmptyFolderSayWhatTheyAre) {
  Folder f;
  EXPECT_THAT(error_of([&] { (void)io::open_folder(f.root.string()); }), HasSubstr("has no frames in rgb/"));
  f.add_frame("x");
  fs::remove(f.depth("x.png"));
  fs::create_symlink(f.depth("x.png"), f.depth("x.png"));
  EXPECT_THAT(error_of([&] { (void)io::open_folder(f.root.string()); }),
              AllOf(HasSubstr("depth image '" + f.depth("x.png") + "'"), HasSubstr("symbolic links")));
}
