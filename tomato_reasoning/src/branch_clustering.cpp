// SPDX-License-Identifier: Apache-2.0
#include "tomato_reasoning/branch_clustering.hpp"

#include "tomato_reasoning/param_tables.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <Eigen/Geometry>

#include "voxel_hash.hpp"

namespace tinyline::tomato_reasoning {

namespace {

struct UnionFind {
  std::vector<int> parent;
  explicit UnionFind(std::size_t n) : parent(n) { std::iota(parent.begin(), parent.end(), 0); }
  int root(int a) {
    while (parent[static_cast<std::size_t>(a)] != a)
      a = parent[static_cast<std::size_t>(a)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(a)])];
    return a;
  }
  void join(int a, int b) {
    a = root(a);
    b = root(b);
    if (a != b) parent[static_cast<std::size_t>(std::max(a, b))] = std::min(a, b);
  }
};

}  // namespace

common::Status validate(const BranchClusteringParams& p) {
  if (common::Status s = common::within_table(p); !s.ok()) return s;
  if (!(p.max_range_m > p.min_range_m)) return common::Status::invalid("ranges must satisfy min_range_m < max_range_m");
  return {};
}

std::vector<Indices> euclidean_clusters(const std::vector<Eigen::Vector3f>& points, const Indices& indices_in,
                                        double tolerance_m) {
  Indices indices;
  if (indices_in.empty()) {
    for (std::size_t k = 0; k < points.size(); ++k)
      if (points[k].allFinite()) indices.push_back(static_cast<int>(k));
  } else {
    for (int k : indices_in)
      if (points[static_cast<std::size_t>(k)].allFinite()) indices.push_back(k);
  }
  if (indices.empty()) return {};
  // Cells of side d / sqrt(3): their diagonal is d, so a cell is one cluster.
  const double cell = tolerance_m / std::sqrt(3.0) * (1.0 - 1e-9);
  const detail::VoxelGrid grid(points, indices, cell);
  const std::size_t nc = grid.num_cells();
  std::vector<Eigen::AlignedBox3f> boxes(nc);
  for (std::size_t c = 0; c < nc; ++c)
    for (const int* m = grid.begin(c); m != grid.end(c); ++m) boxes[c].extend(points[static_cast<std::size_t>(*m)]);
  UnionFind uf(nc);
  // Points in cells more than two apart along an axis are > d apart (2 cells
  // = 1.15 d), so only the 124 surrounding cells can hold a neighbour.
  const float d2 = static_cast<float>(tolerance_m * tolerance_m);
  for (std::size_t c = 0; c < nc; ++c) {
    const detail::CellKey k = grid.key(c);
    for (int dx = -2; dx <= 2; ++dx)
      for (int dy = -2; dy <= 2; ++dy)
        for (int dz = -2; dz <= 2; ++dz) {
          const int o = grid.find({k.x + dx, k.y + dy, k.z + dz});
          if (o <= static_cast<int>(c)) continue;  // each pair once
          if (uf.root(static_cast<int>(c)) == uf.root(o)) continue;
          const auto& a = boxes[c];
          const auto& b = boxes[static_cast<std::size_t>(o)];
          if (a.squaredExteriorDistance(b) > d2) continue;  // even the nearest corners are too far
          bool joined = false;
          for (const int* p = grid.begin(c); p != grid.end(c) && !joined; ++p) {
            const Eigen::Vector3f& pp = points[static_cast<std::size_t>(*p)];
            if (b.squaredExteriorDistance(pp) > d2) continue;
            for (const int* q = grid.begin(static_cast<std::size_t>(o)); q != grid.end(static_cast<std::size_t>(o));
                 ++q) {
              if ((pp - points[static_cast<std::size_t>(*q)]).squaredNorm() <= d2) {
                joined = true;
                break;
              }
            }
          }
          if (joined) uf.join(static_cast<int>(c), o);
        }
  }
  std::vector<int> label(nc, -1);
  std::vector<Indices> out;
  for (std::size_t c = 0; c < nc; ++c) {
    const int r = uf.root(static_cast<int>(c));
    if (label[static_cast<std::size_t>(r)] < 0) {
      label[static_cast<std::size_t>(r)] = static_cast<int>(out.size());
      out.emplace_back();
    }
    Indices& cl = out[static_cast<std::size_t>(label[static_cast<std::size_t>(r)])];
    cl.insert(cl.end(), grid.begin(c), grid.end(c));
  }
  for (auto& cl : out) std::sort(cl.begin(), cl.end());
  std::sort(out.begin(), out.end(), [](const Indices& a, const Indices& b) {
    return a.size() != b.size() ? a.size() > b.size() : a.front() < b.front();
  });
  return out;
}

BranchResult cluster_branches(const ColorCloud& cloud, const Indices& candidates, const BranchClusteringParams& p,
                              const std::vector<Eigen::Vector3f>& viewpoints_in) {
  const std::vector<Eigen::Vector3f> viewpoints =
      viewpoints_in.empty() ? std::vector<Eigen::Vector3f>{Eigen::Vector3f::Zero()} : viewpoints_in;
  BranchResult r;
  if (const common::Status why = validate(p); !why.ok()) {
    r.status = common::Status::invalid("bad branch clustering parameters: " + why.message);
    return r;
  }
  if (const common::Status why = check_cloud(cloud); !why.ok()) {
    r.status = common::Status::invalid("malformed cloud: " + why.message);
    return r;
  }
  for (int k : candidates) {
    if (k < 0 || static_cast<std::size_t>(k) >= cloud.size()) {
      r.status = common::Status::invalid("candidate index " + std::to_string(k) + " outside the cloud of " +
                                         std::to_string(cloud.size()) + " points");
      return r;
    }
  }
  if (candidates.empty()) {
    r.status = common::Status::not_found("no candidate points");
    return r;
  }
  for (auto& idx : euclidean_clusters(cloud.xyz, candidates, p.tolerance_m)) {
    Cluster c;
    Eigen::AlignedBox3d box;
    for (int k : idx) {
      const Eigen::Vector3d q = cloud.xyz[static_cast<std::size_t>(k)].cast<double>();
      c.centroid += q;
      box.extend(q);
    }
    c.centroid /= static_cast<double>(idx.size());
    c.extent_m = box.diagonal().norm();
    c.range_m = std::numeric_limits<double>::infinity();
    for (const auto& v : viewpoints) c.range_m = std::min(c.range_m, (c.centroid - v.cast<double>()).norm());
    c.indices = std::move(idx);
    if (static_cast<int>(c.indices.size()) < p.min_points) {
      c.why_not = "only " + std::to_string(c.indices.size()) + " points (< " + std::to_string(p.min_points) + ")";
    } else if (c.range_m < p.min_range_m || c.range_m > p.max_range_m) {
      c.why_not = "centroid at " + std::to_string(c.range_m) + " m, outside the reach [" +
                  std::to_string(p.min_range_m) + ", " + std::to_string(p.max_range_m) + "] m";
    } else if (c.extent_m > p.max_extent_m) {
      c.why_not = "spans " + std::to_string(c.extent_m) + " m (> " + std::to_string(p.max_extent_m) + " m)";
    } else {
      c.feasible = true;
    }
    r.clusters.push_back(std::move(c));
  }
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t k = 0; k < r.clusters.size(); ++k) {
    if (r.clusters[k].feasible && r.clusters[k].range_m < best) {
      best = r.clusters[k].range_m;
      r.chosen = static_cast<int>(k);
    }
  }
  if (r.chosen < 0) {
    std::string why = std::to_string(r.clusters.size()) + " cluster(s), none feasible";
    if (!r.clusters.empty()) why += " (largest: " + r.clusters.front().why_not + ")";
    r.status = common::Status::not_found(std::move(why));
  }
  return r;
}

}  // namespace tinyline::tomato_reasoning
