// SPDX-License-Identifier: Apache-2.0
// A hash grid of cubic cells over a point set: which points lie in a cell,
// and the cells around a position. Shared by clustering, smoothing and the
// sphere sampler (each needs fixed-radius neighbours, no kd-tree).
#pragma once

#include <cmath>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

namespace tinyline::tomato_reasoning::detail {

struct CellKey {
  std::int32_t x, y, z;
  bool operator==(const CellKey& o) const { return x == o.x && y == o.y && z == o.z; }
};
struct CellKeyHash {
  std::size_t operator()(const CellKey& k) const {
    return static_cast<std::size_t>((static_cast<std::uint64_t>(static_cast<std::uint32_t>(k.x)) * 73856093ULL) ^
                                    (static_cast<std::uint64_t>(static_cast<std::uint32_t>(k.y)) * 19349663ULL) ^
                                    (static_cast<std::uint64_t>(static_cast<std::uint32_t>(k.z)) * 83492791ULL));
  }
};

/// Points (by index into a caller's vector) bucketed by cell. Cells hold
/// their members contiguously (counting sort), so a neighbourhood scan is a
/// few short array walks.
class VoxelGrid {
 public:
  VoxelGrid(const std::vector<Eigen::Vector3f>& points, const std::vector<int>& indices, double cell)
      : cell_(cell), inv_(1.0 / cell) {
    std::vector<int> cell_of(indices.size());
    for (std::size_t k = 0; k < indices.size(); ++k) {
      const CellKey key = key_of(points[static_cast<std::size_t>(indices[k])]);
      auto [it, fresh] = map_.try_emplace(key, static_cast<int>(keys_.size()));
      if (fresh) keys_.push_back(key);
      cell_of[k] = it->second;
    }
    start_.assign(keys_.size() + 1, 0);
    for (int c : cell_of) ++start_[static_cast<std::size_t>(c) + 1];
    for (std::size_t c = 0; c < keys_.size(); ++c) start_[c + 1] += start_[c];
    members_.resize(indices.size());
    std::vector<int> fill(start_.begin(), start_.end() - 1);
    for (std::size_t k = 0; k < indices.size(); ++k)
      members_[static_cast<std::size_t>(fill[static_cast<std::size_t>(cell_of[k])]++)] = indices[k];
  }

  CellKey key_of(const Eigen::Vector3f& p) const {
    return {static_cast<std::int32_t>(std::floor(p.x() * inv_)), static_cast<std::int32_t>(std::floor(p.y() * inv_)),
            static_cast<std::int32_t>(std::floor(p.z() * inv_))};
  }
  std::size_t num_cells() const { return keys_.size(); }
  const CellKey& key(std::size_t c) const { return keys_[c]; }
  /// Cell id of a key, -1 when empty.
  int find(const CellKey& k) const {
    const auto it = map_.find(k);
    return it == map_.end() ? -1 : it->second;
  }
  const int* begin(std::size_t c) const { return members_.data() + start_[c]; }
  const int* end(std::size_t c) const { return members_.data() + start_[c + 1]; }
  std::size_t count(std::size_t c) const { return static_cast<std::size_t>(start_[c + 1] - start_[c]); }
  double cell() const { return cell_; }

  /// Calls f(index) for every point within `radius` of p (radius <= reach * cell).
  template <class F>
  void for_each_within(const std::vector<Eigen::Vector3f>& points, const Eigen::Vector3f& p, float radius,
                       F&& f) const {
    const CellKey k = key_of(p);
    const int reach = std::max(1, static_cast<int>(std::ceil(radius * inv_ - 1e-6)));
    const float r2 = radius * radius;
    for (int dx = -reach; dx <= reach; ++dx)
      for (int dy = -reach; dy <= reach; ++dy)
        for (int dz = -reach; dz <= reach; ++dz) {
          const int c = find({k.x + dx, k.y + dy, k.z + dz});
          if (c < 0) continue;
          for (const int* m = begin(static_cast<std::size_t>(c)); m != end(static_cast<std::size_t>(c)); ++m)
            if ((points[static_cast<std::size_t>(*m)] - p).squaredNorm() <= r2) f(*m);
        }
  }

 private:
  double cell_, inv_;
  std::unordered_map<CellKey, int, CellKeyHash> map_;
  std::vector<CellKey> keys_;
  std::vector<int> start_;
  std::vector<int> members_;
};

}  // namespace tinyline::tomato_reasoning::detail
