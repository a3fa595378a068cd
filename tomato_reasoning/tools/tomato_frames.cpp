// SPDX-License-Identifier: Apache-2.0
// tomato_frames: the tomato pipeline on a folder of RGB-D frames (the layout
// of tomato_reasoning/io/rgbd_files.hpp), without the bus: per frame the
// tomatoes, their pedicel estimates and the pick order on stdout, and with
// --out an annotated copy of each colour image.
//
//   tomato_frames FOLDER [--out DIR] [--gravity X Y Z]
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include <tinyline/common/cli.hpp>
#include <tinyline/common/files.hpp>

#include "tomato_reasoning/io/rgbd_files.hpp"
#include "tomato_reasoning/pipeline.hpp"

namespace cli = tinyline::cli;

namespace tr = tinyline::tomato_reasoning;

namespace {

void print(const std::string& name, const tr::PipelineResult& r) {
  if (!r.status.ok()) {
    std::printf("%s: no tomatoes (%s: %s)\n", name.c_str(), std::string(to_string(r.stage)).c_str(),
                r.status.message.c_str());
    return;
  }
  std::string order;
  for (int i : r.pick_order) order += (order.empty() ? "" : " ") + std::to_string(i);
  std::printf("%s: %zu tomatoes, pick order [%s]\n", name.c_str(), r.tomatoes.size(), order.c_str());
  for (std::size_t i = 0; i < r.tomatoes.size(); ++i) {
    const tr::Tomato& t = r.tomatoes[i];
    const Eigen::Vector3d &c = t.fit.sphere.centre, &d = t.pedicel.expected_dir, &cut = t.cut.point;
    std::printf(
        "  tomato %zu: centre (%.3f, %.3f, %.3f) m, r %.1f mm, pedicel (%.2f, %.2f, %.2f) +-%.0f deg, "
        "cut at (%.3f, %.3f, %.3f)\n",
        i, c.x(), c.y(), c.z(), 1e3 * t.fit.sphere.radius_m, d.x(), d.y(), d.z(), t.pedicel.spread50_deg, cut.x(),
        cut.y(), cut.z());
  }
}

// The annotated images' destinations, checked before any frame is read: never
// an input (`--out FOLDER/depth` would overwrite the depth images), a link, a
// device, a FIFO or a leftover "<name>.part".
void check_outputs(const tr::io::RgbdFolder& f, const std::string& out) {
  namespace fs = std::filesystem;
  std::error_code ec;
  for (const char* sub : {"rgb", "depth"}) {
    if (fs::equivalent(out, fs::path(f.path) / sub, ec)) {
      throw tinyline::files::FileError("output folder '" + out + "' is the input folder's " + sub +
                                       "/: its images would be overwritten; give another folder");
    }
  }
  if (!fs::exists(fs::symlink_status(out, ec))) return;  // made new: nothing in it to replace
  for (const auto& frame : f.frames) {
    tinyline::files::AtomicFile::check((fs::path(out) / (frame.name + ".png")).string(),
                                       {.inputs = {frame.colour, frame.depth}, .what = "annotated image"});
  }
}

}  // namespace

int main(int argc, char** argv) {
  cli::App app{
      "The tomato pipeline on a folder of RGB-D frames (intrinsics.yaml, rgb/NAME.png|jpg, depth/NAME.png "
      "16-bit): tomatoes, pedicel estimates and pick order per frame; with --out, annotated images.",
      "tomato_frames"};
  std::string folder, out;
  std::vector<double> gravity{0.0, 1.0, 0.0};
  app.add_option("FOLDER", folder, "folder of RGB-D frames")->required();
  app.add_option("--out", out, "write DIR/NAME.png: each colour image with the detections drawn on it");
  app.add_option("--gravity", gravity, "gravity's direction in the camera's optical frame (a level camera: 0 1 0)")
      ->expected(3)
      ->check(cli::finite());
  if (const auto rc = cli::parse_command_line(app, argc, argv)) return *rc;
  tr::PipelineParams p;
  p.gravity = Eigen::Vector3d(gravity[0], gravity[1], gravity[2]);
  if (!(p.gravity.norm() > 0)) {
    std::fprintf(stderr, "tomato_frames: --gravity must not be all zero\n");
    return 2;
  }
  p.gravity.normalize();
  int failed = 0;
  try {
    const tr::io::RgbdFolder f = tr::io::open_folder(folder);
    if (!out.empty()) {
      check_outputs(f, out);
      std::filesystem::create_directories(out);
    }
    const tr::TomatoPipeline pipeline(p);
    for (const auto& frame : f.frames) {
      try {
        const tr::io::RgbdImages images = tr::io::read_images(frame, f.intrinsics);
        const tr::PipelineResult r = pipeline.run(tr::io::to_cloud(images, f.intrinsics));
        print(frame.name, r);
        if (out.empty()) continue;
        cv::Mat annotated = images.bgr.clone();
        tr::io::draw_detections(annotated, r, f.intrinsics);
        tr::io::write_image((std::filesystem::path(out) / (frame.name + ".png")).string(), annotated);
      } catch (const tr::io::RgbdFileError& e) {
        std::fprintf(stderr, "tomato_frames: frame %s: %s\n", frame.name.c_str(), e.what());
        ++failed;
      }
    }
    std::printf("%zu frame(s), %d unreadable\n", f.frames.size(), failed);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tomato_frames: %s\n", e.what());
    return 1;
  }
  return failed == 0 ? 0 : 1;
}
