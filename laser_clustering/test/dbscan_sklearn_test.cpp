// SPDX-License-Identifier: Apache-2.0
// Our DBSCAN against scikit-learn's, on random and adversarial data: the
// cases are written here (hex floats, exact), clustered by sklearn_dbscan.py
// in the test virtual env, and compared: identical core and noise sets, the
// same partition of core points, and (our documented border rule) identical
// labels. Every search is compared: FLANN, brute force and, for line scans,
// the ordered-scan fast path.
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "laser_clustering/dbscan.hpp"

namespace lc = tinyline::laser_clustering;
namespace fs = std::filesystem;

namespace {

struct Case {
  std::string name;
  Eigen::MatrixXd points;  // d x n
  lc::DbscanParams params;
  // For line-scan cases, the scan the points came from (fast path input).
  std::vector<double> angle, range, feature;
};

struct SkResult {
  std::vector<int> labels;
  std::vector<int> core;
};

std::vector<Case> make_cases() {
  std::vector<Case> cases;
  std::mt19937 rng(20240611);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);

  // 1. Gaussian blobs with background noise, several dimensions.
  for (int k = 0; k < 40; ++k) {
    const int dim = std::vector<int>{1, 2, 3, 4, 7}[static_cast<std::size_t>(k % 5)];
    const int n = 20 + static_cast<int>(u(rng) * 580);
    const int centres = 1 + k % 6;
    Eigen::MatrixXd c = Eigen::MatrixXd::NullaryExpr(dim, centres, [&] { return 10.0 * u(rng); });
    Eigen::MatrixXd p(dim, n);
    for (int i = 0; i < n; ++i) {
      if (u(rng) < 0.1) {
        for (int d = 0; d < dim; ++d) p(d, i) = 12.0 * u(rng) - 1.0;
      } else {
        const int j = static_cast<int>(u(rng) * centres);
        for (int d = 0; d < dim; ++d) p(d, i) = c(d, j) + 0.5 * g(rng);
      }
    }
    cases.push_back({fmt::format("blobs{}_d{}", k, dim), p, {0.2 + 0.8 * u(rng), 1 + k % 10}, {}, {}, {}});
  }
  // 2. Uniform noise: mostly noise, some tiny clusters.
  for (int k = 0; k < 10; ++k) {
    Eigen::MatrixXd p = Eigen::MatrixXd::NullaryExpr(2, 300, [&] { return u(rng); });
    cases.push_back({fmt::format("uniform{}", k), p, {0.03 + 0.01 * k, 2 + k % 4}, {}, {}, {}});
  }
  // 3. Lattices whose neighbours sit at exactly eps (dyadic, exact in binary),
  //    shifted far from the origin and sheared per row.
  for (int k = 0; k < 12; ++k) {
    const int dim = 2 + k % 2;
    const double step = std::ldexp(1.0, -(k % 4));  // 1, 1/2, 1/4, 1/8
    const double offset = (k % 3 == 0) ? 1024.0 : 0.0;
    std::vector<Eigen::VectorXd> pts;
    const int side = dim == 2 ? 9 : 5;
    for (int a = 0; a < side; ++a)
      for (int b = 0; b < side; ++b)
        for (int c = 0; c < (dim == 3 ? side : 1); ++c) {
          if (u(rng) < 0.25) continue;  // holes make borders and noise
          Eigen::VectorXd v(dim);
          v(0) = offset + step * a;
          v(1) = offset + step * b * ((a % 3 == 0) ? 2 : 1);
          if (dim == 3) v(2) = step * c;
          pts.push_back(v);
        }
    Eigen::MatrixXd p(dim, static_cast<Eigen::Index>(pts.size()));
    for (std::size_t i = 0; i < pts.size(); ++i) p.col(static_cast<Eigen::Index>(i)) = pts[i];
    cases.push_back({fmt::format("lattice{}", k), p, {step, 1 + k % 7}, {}, {}, {}});
  }
  // 4. Duplicates and min_samples edge values.
  {
    Eigen::MatrixXd p(2, 12);
    p << 0, 0, 0, 0, 1, 1, 1, 5, 5, 9, 9.5, 10,  //
        0, 0, 0, 0, 1, 1, 1, 5, 5, 9, 9.5, 10;
    for (const int m : {1, 2, 3, 4, 5, 12, 13}) cases.push_back({fmt::format("dup_m{}", m), p, {0.75, m}, {}, {}, {}});
  }
  // 5. Dumbbells: two dense groups joined by a bridge of border points that
  //    each reach both groups, in shuffled order (tests the border rule).
  for (int k = 0; k < 20; ++k) {
    std::vector<double> xs;
    for (int i = 0; i < 6; ++i) xs.push_back(i * 0.25);
    xs.push_back(2.25);  // reaches 1.25 (core of A) and 3.25 (core of B) at eps 1
    for (int i = 0; i < 6; ++i) xs.push_back(3.25 + i * 0.25);
    std::shuffle(xs.begin(), xs.end(), rng);
    Eigen::MatrixXd p(2, static_cast<Eigen::Index>(xs.size()));
    for (std::size_t i = 0; i < xs.size(); ++i) p.col(static_cast<Eigen::Index>(i)) << xs[i], 0.125 * (k % 3);
    cases.push_back({fmt::format("dumbbell{}", k), p, {1.0, 5}, {}, {}, {}});
  }
  // 6. Tiny inputs.
  cases.push_back({"single", Eigen::MatrixXd::Zero(3, 1), {1.0, 1}, {}, {}, {}});
  cases.push_back({"single_m2", Eigen::MatrixXd::Zero(3, 1), {1.0, 2}, {}, {}, {}});
  // 7. Line scans (256 pixels over 70 degrees): surfaces at several ranges,
  //    drag trails at edges, outliers; with and without a reflectance feature.
  for (int k = 0; k < 30; ++k) {
    Case c;
    c.name = fmt::format("scan{}", k);
    const double fov = 70.0 * std::numbers::pi / 180.0;
    double level = 0.08 + 0.5 * u(rng);
    for (int i = 0; i < 256; ++i) {
      c.angle.push_back((k % 2 ? 1.0 : -1.0) * (-fov / 2 + fov * i / 255.0));
      if (u(rng) < 0.04) level = 0.05 + 0.8 * u(rng);
      double r = level + 0.003 * g(rng);
      if (u(rng) < 0.02) r = 0.05 + 1.5 * u(rng);
      c.range.push_back(r);
      c.feature.push_back(0.01 * std::floor(3.0 * u(rng)));
    }
    if (k % 3 != 0) c.feature.clear();
    lc::OrderedScanPoints s{c.angle, c.range, c.feature};
    c.points = lc::to_points(s);
    c.params = {0.002 + 0.0015 * (k % 12), 2 + k % 8};
    cases.push_back(std::move(c));
  }
  return cases;
}

void write_cases(const std::vector<Case>& cases, const fs::path& path) {
  std::ofstream f(path);
  for (const auto& c : cases) {
    f << fmt::format("case {} {} {} {:a} {}\n", c.name, c.points.cols(), c.points.rows(), c.params.eps,
                     c.params.min_points);
    for (Eigen::Index i = 0; i < c.points.cols(); ++i) {
      for (Eigen::Index d = 0; d < c.points.rows(); ++d) f << fmt::format("{}{:a}", d ? " " : "", c.points(d, i));
      f << "\n";
    }
  }
}

std::map<std::string, SkResult> read_results(const fs::path& path) {
  std::map<std::string, SkResult> out;
  std::ifstream f(path);
  std::string line, name;
  while (std::getline(f, line)) {
    std::istringstream in(line);
    std::string tag;
    in >> tag;
    if (tag == "case") {
      in >> name;
    } else if (tag == "labels" || tag == "core") {
      auto& v = tag == "labels" ? out[name].labels : out[name].core;
      for (int x; in >> x;) v.push_back(x);
    }
  }
  return out;
}

void compare(const Case& c, const SkResult& sk, const lc::DbscanResult& ours, const char* search) {
  SCOPED_TRACE(fmt::format("case {} ({} search, eps {}, min {})", c.name, search, c.params.eps, c.params.min_points));
  ASSERT_TRUE(ours.status.ok()) << ours.status.message;
  const auto n = static_cast<std::size_t>(c.points.cols());
  ASSERT_EQ(sk.labels.size(), n);
  ASSERT_EQ(ours.labels.size(), n);
  std::vector<int> our_core;
  for (std::size_t i = 0; i < n; ++i)
    if (ours.is_core[i]) our_core.push_back(static_cast<int>(i));
  EXPECT_EQ(our_core, sk.core) << "core sets differ";
  for (std::size_t i = 0; i < n; ++i) {
    EXPECT_EQ(ours.labels[i] == lc::kNoise, sk.labels[i] == -1) << "noise differs at point " << i;
  }
  // Same partition of core points: the label maps are a bijection.
  std::map<int, int> ours_to_sk, sk_to_ours;
  for (const int i : sk.core) {
    const int a = ours.labels[static_cast<std::size_t>(i)], b = sk.labels[static_cast<std::size_t>(i)];
    EXPECT_EQ(ours_to_sk.emplace(a, b).first->second, b) << "our cluster " << a << " splits in sklearn at point " << i;
    EXPECT_EQ(sk_to_ours.emplace(b, a).first->second, a) << "sklearn cluster " << b << " splits in ours at point " << i;
  }
  // The documented border rule reproduces sklearn's labels exactly.
  EXPECT_EQ(ours.labels, sk.labels) << "labels differ (border rule or numbering)";
}

}  // namespace

TEST(DbscanSklearn, IdenticalCoreNoiseAndPartitionOnRandomAndAdversarialData) {
  const fs::path python = TINYLINE_VENV_PYTHON;
  ASSERT_TRUE(fs::exists(python)) << "test virtual env missing: " << python << " (run scripts/bootstrap)";
  const fs::path script = fs::path(TINYLINE_SOURCE_DIR) / "laser_clustering/test/sklearn_dbscan.py";
  const fs::path dir = fs::path(testing::TempDir()) / fmt::format("tl_dbscan_sklearn_{}", ::getpid());
  fs::create_directories(dir);
  const auto cases = make_cases();
  write_cases(cases, dir / "cases.txt");
  const std::string cmd = fmt::format("'{}' '{}' '{}' '{}'", python.string(), script.string(),
                                      (dir / "cases.txt").string(), (dir / "labels.txt").string());
  ASSERT_EQ(std::system(cmd.c_str()), 0) << "failed: " << cmd;
  const auto sk = read_results(dir / "labels.txt");
  ASSERT_EQ(sk.size(), cases.size());

  lc::OrderedScanDbscan fast;
  int scan_cases = 0;
  std::size_t clusters = 0, noise = 0, borders = 0, shared_borders = 0;
  for (const auto& c : cases) {
    const auto it = sk.find(c.name);
    ASSERT_NE(it, sk.end()) << c.name;
    const auto flann = lc::dbscan(c.points, c.params);
    compare(c, it->second, flann, "flann");
    clusters += static_cast<std::size_t>(flann.num_clusters);
    noise += flann.num_noise;
    for (std::size_t i = 0; i < flann.labels.size(); ++i) {
      if (flann.is_core[i] || flann.labels[i] < 0) continue;
      ++borders;
      // A border point within eps of core points of two clusters.
      std::vector<int> near;
      for (Eigen::Index j = 0; j < c.points.cols(); ++j) {
        if (flann.is_core[static_cast<std::size_t>(j)] &&
            (c.points.col(static_cast<Eigen::Index>(i)) - c.points.col(j)).squaredNorm() <=
                c.params.eps * c.params.eps) {
          near.push_back(flann.labels[static_cast<std::size_t>(j)]);
        }
      }
      if (std::find_if(near.begin(), near.end(), [&](int l) { return l != near.front(); }) != near.end())
        ++shared_borders;
    }
    compare(c, it->second, lc::dbscan_brute_force(c.points, c.params), "brute force");
    if (!c.angle.empty()) {
      ++scan_cases;
      compare(c, it->second, fast.run({c.angle, c.range, c.feature}, c.params), "ordered scan");
    }
  }
  EXPECT_EQ(scan_cases, 30);
  // The data exercise every kind of point (guards against degenerate cases).
  EXPECT_GT(clusters, 300u);
  EXPECT_GT(noise, 1000u);
  EXPECT_GT(borders, 300u);
  EXPECT_GE(shared_borders, 20u) << "no border point was reachable from two clusters";
  std::printf("%zu clusters, %zu noise, %zu border points (%zu reachable from two clusters)\n", clusters, noise,
              borders, shared_borders);
  fs::remove_all(dir);
}
