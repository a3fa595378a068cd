// SPDX-License-Identifier: Apache-2.0
// tomato_dump: one simulated truss through the pipeline, written as CSV for
// the pictures of docs/tomato_reasoning.md (scripts/plots/tomato_figures.py):
//
//   tomato_dump CLASS SEED OUT_DIR [KERNEL_KAPPA]
//
// OUT_DIR/points.csv   x,y,z,r,g,b,red   every finite point (every 3rd
//                      pixel), red = passed the HSI filter (camera frame)
// OUT_DIR/spheres.csv  one row per fitted sphere: centre, radius, pick rank,
//                      expected pedicel, spreads, the matched true centre,
//                      radius and pedicel (NaN when unmatched)
// OUT_DIR/edges.csv    contact graph (Eq. 4.17)
// OUT_DIR/grid_K.csv   pedicel density of sphere K on (phi, theta) in a
//                      gravity-aligned frame (z up; Figure 4.5), 72 x 36
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>

#include "tomato_reasoning/eval/scenario.hpp"
#include "tomato_reasoning/hsi_filter.hpp"
#include "tomato_reasoning/pipeline.hpp"

#include <tinyline/common/cli.hpp>
#include <tinyline/common/files.hpp>

using namespace tinyline;
using namespace tinyline::tomato_reasoning;

int main(int argc, char** argv) try {
  cli::App app{
      "One simulated truss through the tomato pipeline, written as CSV for the pictures of "
      "docs/tomato_reasoning.md.",
      "tomato_dump"};
  std::string class_name, out_dir;
  std::uint64_t seed = 0;
  std::optional<double> kernel_kappa;
  app.add_option("CLASS", class_name, "truss complexity class")->required()->check(cli::one_of({"A", "B", "C"}));
  app.add_option("SEED", seed, "truss seed")->required()->check(cli::non_negative());
  app.add_option("OUT_DIR", out_dir, "output directory")->required();
  app.add_option("KERNEL_KAPPA", kernel_kappa, "force.kernel_kappa (default: the fitted one)")
      ->check(cli::non_negative());
  if (const auto rc = cli::parse_command_line(app, argc, argv)) return *rc;
  const auto cls = sim::parse_truss_class(class_name);
  const std::filesystem::path out = out_dir;
  for (const char* name : {"points.csv", "spheres.csv", "edges.csv"})  // checked before the truss is made
    if (!files::output_allowed("tomato_dump", (out / name).string())) return 1;
  std::filesystem::create_directories(out);
  const eval::Scenario s = eval::make_scenario(*cls, seed);
  PipelineParams p;
  p.gravity = s.gravity_camera;
  if (kernel_kappa) p.force.kernel_kappa = *kernel_kappa;
  const PipelineResult r = TomatoPipeline(p).run(s.cloud());
  std::printf("class %c seed %llu: %zu true tomatoes, %zu spheres (%s%s%s)\n", char(*cls),
              static_cast<unsigned long long>(seed), s.truth.size(), r.tomatoes.size(),
              r.status.ok() ? "ok" : std::string(to_string(r.stage)).c_str(), r.status.ok() ? "" : ": ",
              r.status.message.c_str());

  files::AtomicStream pts((out / "points.csv").string());
  pts << "x,y,z,r,g,b,red\n";
  const ColorCloud& c = s.cloud();
  const HsiFilter hsi(p.hsi);
  for (std::size_t i = 0; i < c.size(); i += 3) {
    if (!c.finite(i)) continue;
    const bool red = hsi.passes(c.rgb[i]);
    pts << c.xyz[i].x() << ',' << c.xyz[i].y() << ',' << c.xyz[i].z() << ',' << int(c.rgb[i][0]) << ','
        << int(c.rgb[i][1]) << ',' << int(c.rgb[i][2]) << ',' << int(red) << '\n';
  }
  pts.commit();
  // Gravity-aligned frame for the distribution: z up (against gravity).
  const Eigen::Vector3d up = -s.gravity_camera.normalized();
  Eigen::Matrix3d R;  // rows: the new axes in camera coordinates
  const Eigen::Vector3d x = up.unitOrthogonal(), y = up.cross(x);
  R.row(0) = x;
  R.row(1) = y;
  R.row(2) = up;
  files::AtomicStream sph((out / "spheres.csv").string());
  sph << "k,cx,cy,cz,radius,pick_rank,ex,ey,ez,spread50_deg,spread90_deg,edges,tcx,tcy,tcz,tradius,tpx,tpy,tpz,gux,guy,"
         "guz,gtx,gty,gtz\n";
  for (std::size_t k = 0; k < r.tomatoes.size(); ++k) {
    const Tomato& t = r.tomatoes[k];
    int match = -1;
    for (std::size_t j = 0; j < s.truth.size(); ++j)
      if ((s.truth[j].centre_m - t.fit.sphere.centre).norm() <= 0.01) match = int(j);
    const double nan = std::nan("");
    const Eigen::Vector3d tc = match >= 0 ? s.truth[std::size_t(match)].centre_m : Eigen::Vector3d::Constant(nan);
    const Eigen::Vector3d tp = match >= 0 ? s.truth[std::size_t(match)].pedicel_dir : Eigen::Vector3d::Constant(nan);
    const double tr = match >= 0 ? s.truth[std::size_t(match)].radius_m : nan;
    const Eigen::Vector3d eu = R * t.pedicel.expected_dir, tu = R * tp;
    sph << k << ',' << t.fit.sphere.centre.x() << ',' << t.fit.sphere.centre.y() << ',' << t.fit.sphere.centre.z()
        << ',' << t.fit.sphere.radius_m << ',' << t.pick_rank << ',' << t.pedicel.expected_dir.x() << ','
        << t.pedicel.expected_dir.y() << ',' << t.pedicel.expected_dir.z() << ',' << t.pedicel.spread50_deg << ','
        << t.pedicel.spread90_deg << ',' << t.pedicel.edges << ',' << tc.x() << ',' << tc.y() << ',' << tc.z() << ','
        << tr << ',' << tp.x() << ',' << tp.y() << ',' << tp.z() << ',' << eu.x() << ',' << eu.y() << ',' << eu.z()
        << ',' << tu.x() << ',' << tu.y() << ',' << tu.z() << '\n';
    files::AtomicStream g((out / ("grid_" + std::to_string(k) + ".csv")).string());
    for (const auto& row : t.pedicel.distribution.rotated(R).grid(72, 36)) {
      for (std::size_t j = 0; j < row.size(); ++j) g << (j ? "," : "") << row[j];
      g << '\n';
    }
    g.commit();
  }
  sph.commit();
  files::AtomicStream e((out / "edges.csv").string());
  e << "i,j,gap_m\n";
  for (const auto& edge : r.edges) e << edge.i << ',' << edge.j << ',' << edge.gap_m << '\n';
  e.commit();
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "tomato_dump: %s\n", e.what());
  return 1;
}
