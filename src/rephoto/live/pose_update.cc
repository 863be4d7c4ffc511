#include "rephoto/live/pose_update.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

#include "rephoto/core/error.h"

namespace rephoto::live {

namespace {

struct Similarity {
  double s = 1;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  double spread = 0;  // RMS distance of the used new centres from their centroid
};

// after = s R before + t over the photos with use[i] (Umeyama 1991); R = I (scale about the
// centroids only) with fewer than 3 photos or centres on a line.
Similarity FitSimilarity(const std::vector<camera::Pose>& before,
                         const std::vector<camera::Pose>& after, const std::vector<uint8_t>& use) {
  Similarity f;
  Eigen::Vector3d mb = Eigen::Vector3d::Zero(), ma = Eigen::Vector3d::Zero();
  size_t n = 0;
  for (size_t i = 0; i < before.size(); ++i) {
    if (!use[i]) continue;
    mb += before[i].Center();
    ma += after[i].Center();
    ++n;
  }
  if (n == 0) return f;
  mb /= double(n);
  ma /= double(n);
  double vb = 0, va = 0;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < before.size(); ++i) {
    if (!use[i]) continue;
    const Eigen::Vector3d b = before[i].Center() - mb, a = after[i].Center() - ma;
    vb += b.squaredNorm();
    va += a.squaredNorm();
    cov += a * b.transpose();
  }
  f.s = vb > 0 ? std::sqrt(va / vb) : 1.0;
  if (n >= 3 && vb > 0) {
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
    const Eigen::Vector3d sv = svd.singularValues();
    if (sv[1] > 1e-9 * sv[0]) {
      Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
      if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) S(2, 2) = -1;
      f.R = svd.matrixU() * S * svd.matrixV().transpose();
      f.s = (sv.asDiagonal() * S).trace() / vb;
    }
  }
  f.t = ma - f.s * f.R * mb;
  f.spread = std::sqrt(va / double(n));
  return f;
}

}  // namespace

std::vector<PoseChange> ComparePoses(const std::vector<camera::Pose>& before,
                                     const std::vector<camera::Pose>& after,
                                     const PoseUpdateOptions& options) {
  REPHOTO_CHECK(before.size() == after.size(), "pose update: {} poses before, {} after",
                before.size(), after.size());
  const size_t n = before.size();
  std::vector<PoseChange> out(n);
  if (n == 0) return out;
  // The similarity is fitted on all photos, then again on those it carries within the
  // thresholds (when at least 3 are), so that one refined photo does not tilt the fit and make
  // its neighbours look refined too.
  std::vector<uint8_t> use(n, 1);
  for (int round = 0; round < 3; ++round) {
    const Similarity sim = FitSimilarity(before, after, use);
    std::vector<uint8_t> inlier(n, 0);
    size_t inliers = 0;
    for (size_t i = 0; i < n; ++i) {
      PoseChange& c = out[i];
      c.scale = sim.s;
      const Eigen::Vector3d carried = sim.s * sim.R * before[i].Center() + sim.t;
      c.moved = sim.spread > 0 ? (after[i].Center() - carried).norm() / sim.spread : 0.0;
      // Old rotation carried by the similarity: cam_from_world' = R_old R^T.
      const Eigen::Matrix3d delta =
          after[i].rotation * (before[i].rotation * sim.R.transpose()).transpose();
      c.rotated_degrees = std::acos(std::clamp((delta.trace() - 1) / 2, -1.0, 1.0)) * 180 / M_PI;
      c.refresh_depth = c.moved > options.move_fraction || c.rotated_degrees > options.rotate_degrees;
      inlier[i] = !c.refresh_depth;
      inliers += inlier[i];
    }
    if (inlier == use || inliers < 3) break;
    use = inlier;
  }
  return out;
}

double IntrinsicsChange(const camera::Camera& before, const camera::Camera& after) {
  if (before.model != after.model || before.width != after.width ||
      before.height != after.height || before.params.size() != after.params.size())
    return 1.0;
  double change = 0;
  for (size_t j = 0; j < before.params.size(); ++j)
    change = std::max(change, std::abs(after.params[j] - before.params[j]) /
                                  std::max(1.0, std::abs(before.params[j])));
  return change;
}

}  // namespace rephoto::live
