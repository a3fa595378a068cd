// SPDX-License-Identifier: Apache-2.0
#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <random>
#include <set>

#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/extract_clusters.h>

#include "tomato_reasoning/branch_clustering.hpp"

using namespace tinyline::tomato_reasoning;

namespace {

// Blobs of points (fruit-sized) scattered so that some chains join and some do not.
std::vector<Eigen::Vector3f> blobs(std::uint32_t seed, int n_blobs, int per_blob) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> where(-0.25f, 0.25f), off(-0.03f, 0.03f);
  std::vector<Eigen::Vector3f> pts;
  for (int b = 0; b < n_blobs; ++b) {
    const Eigen::Vector3f c(where(rng), where(rng), 0.5f + where(rng));
    for (int k = 0; k < per_blob; ++k) pts.emplace_back(c + Eigen::Vector3f(off(rng), off(rng), off(rng)));
  }
  return pts;
}

std::set<std::set<int>> partition(const std::vector<Indices>& clusters) {
  std::set<std::set<int>> out;
  for (const auto& c : clusters) out.insert(std::set<int>(c.begin(), c.end()));
  return out;
}

}  // namespace

TEST(BranchClustering, SamePartitionAsPclEuclideanClusterExtraction) {
  for (std::uint32_t seed = 1; seed <= 6; ++seed) {
    for (double tol : {0.02, 0.06}) {
      const auto pts = blobs(seed, 12, 150);
      pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
      for (const auto& p : pts) cloud->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
      pcl::search::KdTree<pcl::PointXYZ>::Ptr tree(new pcl::search::KdTree<pcl::PointXYZ>);
      std::vector<pcl::PointIndices> pcl_clusters;
      pcl::EuclideanClusterExtraction<pcl::PointXYZ> ec;
      ec.setClusterTolerance(tol);
      ec.setMinClusterSize(1);
      ec.setMaxClusterSize(1000000);
      ec.setSearchMethod(tree);
      ec.setInputCloud(cloud);
      ec.extract(pcl_clusters);
      std::vector<Indices> ref;
      for (const auto& c : pcl_clusters) ref.emplace_back(c.indices.begin(), c.indices.end());
      const auto ours = euclidean_clusters(pts, {}, tol);
      EXPECT_EQ(partition(ours), partition(ref)) << "seed " << seed << " tolerance " << tol;
      EXPECT_GT(ours.size(), 1u);
    }
  }
}

TEST(BranchClustering, ChoosesTheClosestFeasibleBranch) {
  ColorCloud c;
  auto blob = [&](const Eigen::Vector3f& at, int n) {
    for (int k = 0; k < n; ++k)
      c.push_back(at + Eigen::Vector3f(0.001f * (k % 20), 0.001f * (k / 20 % 20), 0.0005f * (k / 400)), {200, 40, 30});
  };
  blob({0, 0, 0.6f}, 400);      // a branch at 0.6 m
  blob({0.3f, 0, 0.45f}, 400);  // a nearer one
  blob({0, 0.1f, 0.3f}, 20);    // nearest, but a speck (too few points)
  blob({0, 0, 2.0f}, 400);      // out of reach
  Indices all(c.size());
  for (std::size_t k = 0; k < all.size(); ++k) all[k] = int(k);
  const BranchResult r = cluster_branches(c, all);
  ASSERT_EQ(r.clusters.size(), 4u);
  ASSERT_NE(r.branch(), nullptr);
  EXPECT_NEAR(r.branch()->centroid.z(), 0.45, 0.01);
  int infeasible = 0;
  for (const auto& cl : r.clusters) {
    if (cl.feasible) continue;
    ++infeasible;
    EXPECT_FALSE(cl.why_not.empty());
  }
  EXPECT_EQ(infeasible, 2);
  // Seen from a second viewpoint beside the far branch, that one is closer.
  const BranchResult r2 = cluster_branches(c, all, {}, {Eigen::Vector3f(0, 0, 0.3f)});
  EXPECT_NEAR(r2.branch()->centroid.z(), 0.6, 0.01);
}

TEST(BranchClustering, BadInputGivesNoBranchAndTheReason) {
  ColorCloud c;
  c.push_back({0, 0, 0.5f}, {200, 40, 30});
  EXPECT_EQ(cluster_branches(c, {}).status.message, "no candidate points");
  EXPECT_NE(cluster_branches(c, {7}).status.message.find("outside the cloud"), std::string::npos);
  const BranchResult one = cluster_branches(c, {0});  // a single point
  EXPECT_EQ(one.chosen, -1);
  EXPECT_NE(one.status.message.find("none feasible"), std::string::npos);
  BranchClusteringParams bad;
  bad.tolerance_m = -1;
  EXPECT_NE(cluster_branches(c, {0}, bad).status.message.find("tolerance_m"), std::string::npos);
  ColorCloud nan;
  nan.push_back({NAN, 0, 0}, {200, 40, 30});
  EXPECT_TRUE(cluster_branches(nan, {0}).clusters.empty());
}
