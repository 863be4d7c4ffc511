#include "rephoto/render/point_radius.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"

namespace rephoto::render {
namespace {

// Implicit kd-tree: the index array is arranged so that every subrange [begin, end) has its
// median element at mid = (begin + end) / 2, split along axis_[mid].
class KdTree {
 public:
  explicit KdTree(const std::vector<Eigen::Vector3f>& points)
      : points_(points), order_(points.size()), axis_(points.size(), 0) {
    std::iota(order_.begin(), order_.end(), 0u);
    Build(0, order_.size());
  }

  // The k smallest squared distances from `query` to points other than `self`, ascending.
  void Nearest(const Eigen::Vector3f& query, uint32_t self, int k, std::vector<float>& best) const {
    best.clear();
    Search(0, order_.size(), query, self, k, best);
  }

 private:
  void Build(size_t begin, size_t end) {
    if (end - begin <= 1) return;
    Eigen::Vector3f lo = points_[order_[begin]], hi = lo;
    for (size_t i = begin; i < end; ++i) {
      lo = lo.cwiseMin(points_[order_[i]]);
      hi = hi.cwiseMax(points_[order_[i]]);
    }
    int axis = 0;
    (hi - lo).maxCoeff(&axis);
    const size_t mid = (begin + end) / 2;
    std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                     [&](uint32_t a, uint32_t b) {
                       const float pa = points_[a][axis], pb = points_[b][axis];
                       return pa < pb || (pa == pb && a < b);
                     });
    axis_[mid] = static_cast<uint8_t>(axis);
    Build(begin, mid);
    Build(mid + 1, end);
  }

  static void Insert(std::vector<float>& best, int k, float d2) {
    if (static_cast<int>(best.size()) == k) {
      if (d2 >= best.back()) return;
      best.pop_back();
    }
    best.insert(std::upper_bound(best.begin(), best.end(), d2), d2);
  }

  void Search(size_t begin, size_t end, const Eigen::Vector3f& query, uint32_t self, int k,
              std::vector<float>& best) const {
    if (begin >= end) return;
    const size_t mid = (begin + end) / 2;
    const uint32_t index = order_[mid];
    if (index != self) Insert(best, k, (points_[index] - query).squaredNorm());
    if (end - begin == 1) return;
    const int axis = axis_[mid];
    const float delta = query[axis] - points_[index][axis];
    const bool left_first = delta < 0;
    if (left_first) {
      Search(begin, mid, query, self, k, best);
    } else {
      Search(mid + 1, end, query, self, k, best);
    }
    if (static_cast<int>(best.size()) < k || delta * delta < best.back()) {
      if (left_first) {
        Search(mid + 1, end, query, self, k, best);
      } else {
        Search(begin, mid, query, self, k, best);
      }
    }
  }

  const std::vector<Eigen::Vector3f>& points_;
  std::vector<uint32_t> order_;
  std::vector<uint8_t> axis_;
};

}  // namespace

std::vector<float> KthNeighborDistances(const std::vector<Eigen::Vector3f>& points, int k) {
  REPHOTO_CHECK(k >= 1, "point radius: k = {} must be at least 1", k);
  std::vector<float> distances(points.size(), 0.0f);
  if (points.size() < 2) return distances;
  const KdTree tree(points);
  ParallelFor(0, static_cast<int64_t>(points.size()), 4096, [&](int64_t begin, int64_t end) {
    std::vector<float> best;
    best.reserve(k + 1);
    for (int64_t i = begin; i < end; ++i) {
      tree.Nearest(points[i], static_cast<uint32_t>(i), k, best);
      distances[i] = best.empty() ? 0.0f : std::sqrt(best.back());
    }
  });
  return distances;
}

}  // namespace rephoto::render
