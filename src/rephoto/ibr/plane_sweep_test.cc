#include "rephoto/ibr/plane_sweep.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "rephoto/core/error.h"
#include "rephoto/ibr/demo_photos_test_util.h"
#include "rephoto/testing/testing.h"

namespace rephoto::ibr {
namespace {

TEST(PlaneSweep, DepthOfTheDemoSceneAgreesWithTheGroundTruth) {
  // 12 views 30 degrees apart at 320x240; the reference is matched against its 4 nearest
  // neighbours over the true depth range widened by 25 %.
  synth::DemoSceneOptions options;
  options.image_width = 320;
  options.image_height = 240;
  options.camera_count = 12;
  options.ground_cells = 100;
  options.object_bands = 60;
  const testing::DemoPhotos demo =
      testing::MakeDemoPhotos(options, rephoto::testing::MakeTempDir());
  std::vector<camera::Pose> poses;
  for (const auto& v : demo.scene.views) poses.push_back(v.cam_from_world);
  const size_t reference = 0;
  const Image truth = demo.TrueDepth(reference);
  double near = 1e9, far = 0;
  for (size_t i = 0; i < truth.pixel_count(); ++i) {
    if (!std::isfinite(truth.data()[i])) continue;
    near = std::min<double>(near, truth.data()[i]);
    far = std::max<double>(far, truth.data()[i]);
  }
  const std::vector<size_t> neighbors = SelectNeighbors(poses, reference, 3.3, 4);
  ASSERT_EQ(neighbors.size(), 4u);
  PlaneSweepOptions sweep;
  sweep.min_depth = near / 1.25;
  sweep.max_depth = far * 1.25;
  const camera::Camera camera = demo.scene.CameraOf(demo.scene.views[reference]);
  const PlaneSweepView ref{camera, poses[reference], &demo.photos[reference]};
  std::vector<PlaneSweepView> others;
  for (size_t n : neighbors) others.push_back({camera, poses[n], &demo.photos[n]});
  const PlaneSweepResult result = ComputePlaneSweepDepth(ref, others, sweep);
  ASSERT_EQ(result.depth.width(), 320);
  ASSERT_EQ(result.depth.height(), 240);
  EXPECT_EQ(result.camera, camera);

  // Tolerance: 2 % of the true depth (about 2 plane steps at the object).
  size_t surface = 0, estimated = 0, accurate = 0;
  for (size_t i = 0; i < truth.pixel_count(); ++i) {
    const float t = truth.data()[i], d = result.depth.data()[i];
    if (!std::isfinite(t)) continue;
    ++surface;
    if (!std::isfinite(d)) continue;
    ++estimated;
    accurate += std::abs(d - t) <= 0.02f * t;
  }
  const double coverage = static_cast<double>(estimated) / surface;
  const double precision = static_cast<double>(accurate) / estimated;
  const double recall = static_cast<double>(accurate) / surface;
  std::cout << "plane sweep: coverage " << coverage << ", within 2 % of the truth: " << precision
            << " of the estimates, " << recall << " of the surface pixels\n";
  EXPECT_GT(coverage, 0.6);
  EXPECT_GT(precision, 0.6);

  // Multi-view consistency with the two nearest neighbours' own depth maps removes most of the
  // wrong matches.
  std::vector<Image> depths = {result.depth};
  std::vector<std::vector<size_t>> lists(3);
  for (int k = 0; k < 2; ++k) {
    const size_t view = neighbors[k];
    const std::vector<size_t> own = SelectNeighbors(poses, view, 3.3, 4);
    std::vector<PlaneSweepView> views;
    for (size_t n : own) views.push_back({camera, poses[n], &demo.photos[n]});
    depths.push_back(
        ComputePlaneSweepDepth({camera, poses[view], &demo.photos[view]}, views, sweep).depth);
  }
  lists[0] = {1, 2};
  lists[1] = {0};
  lists[2] = {0};
  std::vector<DepthView> depth_views;
  for (int k = 0; k < 3; ++k) {
    depth_views.push_back({camera, poses[k == 0 ? reference : neighbors[k - 1]], &depths[k]});
  }
  FilterInconsistentDepths(depth_views, lists, 0.02, 1);
  size_t kept = 0, kept_accurate = 0;
  for (size_t i = 0; i < truth.pixel_count(); ++i) {
    const float t = truth.data()[i], d = depths[0].data()[i];
    if (!std::isfinite(t) || !std::isfinite(d)) continue;
    ++kept;
    kept_accurate += std::abs(d - t) <= 0.02f * t;
  }
  const double filtered_precision = static_cast<double>(kept_accurate) / kept;
  std::cout << "after the consistency filter: coverage " << static_cast<double>(kept) / surface
            << ", within 2 %: " << filtered_precision << " of the estimates, "
            << static_cast<double>(kept_accurate) / surface << " of the surface pixels\n";
  EXPECT_GT(filtered_precision, 0.85);
  EXPECT_GT(static_cast<double>(kept) / surface, 0.4);
}

TEST(PlaneSweep, NeighboursOnARingAreTheNearestConvergingViews) {
  std::vector<camera::Pose> poses;
  for (int i = 0; i < 12; ++i) {
    const double angle = 2 * std::numbers::pi * i / 12;
    const Eigen::Vector3d centre(3 * std::cos(angle), 3 * std::sin(angle), 0);
    const Eigen::Vector3d forward = -centre.normalized();
    const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();
    camera::Pose pose;
    pose.rotation.row(0) = right.transpose();
    pose.rotation.row(1) = forward.cross(right).transpose();
    pose.rotation.row(2) = forward.transpose();
    pose.translation = -pose.rotation * centre;
    poses.push_back(pose);
  }
  // Views 1 and 11 are 30 degrees away, 2 and 10 60 degrees (the limit), the rest beyond.
  std::vector<size_t> n = SelectNeighbors(poses, 0, 3.0, 4);
  ASSERT_EQ(n.size(), 4u);
  EXPECT_EQ(std::min(n[0], n[1]), 1u);
  EXPECT_EQ(std::max(n[0], n[1]), 11u);
  EXPECT_EQ(std::min(n[2], n[3]), 2u);
  EXPECT_EQ(std::max(n[2], n[3]), 10u);
  EXPECT_EQ(SelectNeighbors(poses, 0, 3.0, 1).size(), 1u);
  EXPECT_THROW(SelectNeighbors(poses, 12, 3.0, 4), Error);
}

TEST(PlaneSweep, InvalidOptionsThrow) {
  Image photo(16, 16, 3, 0.5f);
  camera::Camera camera{camera::CameraModel::kPinhole, 16, 16, {16, 16, 8, 8}};
  const PlaneSweepView view{camera, {}, &photo};
  PlaneSweepOptions options;
  EXPECT_THROW(ComputePlaneSweepDepth(view, {&view, 1}, options), Error);  // no depth range
  options.min_depth = 1;
  options.max_depth = 2;
  EXPECT_THROW(ComputePlaneSweepDepth(view, {}, options), Error);
  options.window = 4;
  EXPECT_THROW(ComputePlaneSweepDepth(view, {&view, 1}, options), Error);
}

}  // namespace
}  // namespace rephoto::ibr
