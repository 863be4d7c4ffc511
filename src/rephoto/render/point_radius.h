// Splat radii for point clouds from the local point density.
//
// Thread safety: reentrant (no shared state).
#pragma once

#include <Eigen/Core>
#include <vector>

namespace rephoto::render {

// For each point, the Euclidean distance to its k-th nearest other point (k >= 1; duplicates of
// the point itself count as neighbours at distance 0). With fewer than k other points, the
// distance to the farthest one; a single point gets 0. Exact (kd-tree), parallel over points,
// deterministic. O(n log n) build, about O(k log n) per query.
std::vector<float> KthNeighborDistances(const std::vector<Eigen::Vector3f>& points, int k);

}  // namespace rephoto::render
