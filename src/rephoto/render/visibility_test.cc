// render/visibility.h against closed forms: projections by hand, facing cosines, the image
// border, the lens's fold-over, and occlusion by a wall of two triangles between camera and
// points.
#include "rephoto/render/visibility.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "rephoto/render/render_model.h"

namespace rephoto::render {
namespace {

using camera::Camera;
using camera::CameraModel;
using camera::Pose;

Camera Pinhole() { return Camera{CameraModel::kPinhole, 640, 480, {500, 500, 320, 240}}; }

TEST(Visibility, SightingProjectsFacesAndKeepsInsideTheImage) {
  const ViewGeometry view(Pinhole(), Pose());  // at the origin, looking along +z
  const VisibilityRule rule;
  // (0.2, -0.1, 2): pixel (320 + 500 * 0.1, 240 - 500 * 0.05) = (370, 215).
  const Eigen::Vector3d point(0.2, -0.1, 2.0);
  const Eigen::Vector3d to_camera = -point;
  auto seen = Sighting(view, point, Eigen::Vector3d::Zero(), rule);
  ASSERT_TRUE(seen.has_value());
  EXPECT_NEAR(seen->pixel.x(), 370.0, 1e-9);
  EXPECT_NEAR(seen->pixel.y(), 215.0, 1e-9);
  EXPECT_EQ(seen->cosine, 1.0);
  EXPECT_NEAR(seen->distance, to_camera.norm(), 1e-12);
  // A normal at angle a from the direction to the camera: cosine cos(a); 0.05 is the default.
  const Eigen::Vector3d axis = to_camera.normalized();
  const Eigen::Vector3d side = axis.cross(Eigen::Vector3d::UnitX()).normalized();
  for (double angle : {0.0, 1.0, 1.5, std::acos(0.06), std::acos(0.04), 2.0}) {
    const Eigen::Vector3d normal = std::cos(angle) * axis + std::sin(angle) * side;
    seen = Sighting(view, point, 3.0 * normal, rule);  // the normal's length does not matter
    EXPECT_EQ(seen.has_value(), std::cos(angle) > 0.05) << angle;
    if (seen) EXPECT_NEAR(seen->cosine, std::cos(angle), 1e-12);
  }
  // The border: x = 0.4 px is outside the default half pixel, 0.6 px inside.
  for (double x : {0.4, 0.6, 639.4, 639.6}) {
    const Eigen::Vector3d p((x - 320.0) / 500.0 * 2.0, 0.0, 2.0);
    EXPECT_EQ(Sighting(view, p, Eigen::Vector3d::Zero(), rule).has_value(), x > 0.5 && x < 639.5)
        << x;
  }
  EXPECT_FALSE(Sighting(view, Eigen::Vector3d(0, 0, -1), Eigen::Vector3d::Zero(), rule));
}

// A point outside the lens's field that strong barrel distortion folds into the image.
TEST(Visibility, PointsTheDistortionFoldsIntoTheImageAreNotSeen) {
  const Camera camera{CameraModel::kRadial, 640, 480, {300, 320, 240, -0.2, 0.0}};
  const ViewGeometry view(camera, Pose());
  const Eigen::Vector3d folded(2.5, 0.0, 1.0);  // projects to x = 132.5 (camera_test)
  ASSERT_TRUE(camera.ImgFromCam(folded).has_value());
  EXPECT_FALSE(Sighting(view, folded, Eigen::Vector3d::Zero(), VisibilityRule{}));
  EXPECT_FALSE(UsableProjection(view, folded, 0.5));
  const Eigen::Vector3d inside(0.5, 0.0, 1.0);  // r = 0.5 < 1.29
  EXPECT_TRUE(Sighting(view, inside, Eigen::Vector3d::Zero(), VisibilityRule{}));
}

// A wall (two triangles) at z = 1 covering x in [-1, 0]: of 40 points at z = 2 along x in
// [-2, 2], those with x / 2 in the wall's shadow (x < 0 seen through the wall's x in [-1, 0])
// are hidden; the others are visited, in order.
TEST(Visibility, OcclusionBatchVisitsTheUnhiddenPointsInOrder) {
  mesh::Mesh wall;
  wall.positions = {Eigen::Vector3f(-1, -1, 1), Eigen::Vector3f(0, -1, 1), Eigen::Vector3f(0, 1, 1),
                    Eigen::Vector3f(-1, 1, 1)};
  wall.faces = {{0, 1, 2}, {0, 2, 3}};
  const RenderModel model(wall);
  OcclusionBatch batch(model.scene(), Eigen::Vector3d::Zero(), VisibilityRule{}.occlusion_epsilon);
  std::vector<uint32_t> visited;
  auto visit = [&](uint32_t tag) { visited.push_back(tag); };
  std::vector<uint32_t> expected;
  for (uint32_t i = 0; i < 40; ++i) {
    const double x = -1.95 + 0.1 * i;  // the ray crosses z = 1 at x / 2
    batch.Add(Eigen::Vector3d(x, 0.05, 2.0), i, visit);
    if (!(x / 2 > -1 && x / 2 < 0)) expected.push_back(i);
  }
  batch.Flush(visit);
  EXPECT_EQ(visited, expected);
  // A point on the wall itself is not hidden by it (epsilon), one just behind it is.
  visited.clear();
  batch.Add(Eigen::Vector3d(-0.5, 0.0, 1.0), 1, visit);
  batch.Add(Eigen::Vector3d(-0.5, 0.0, 1.01), 2, visit);
  batch.Flush(visit);
  EXPECT_EQ(visited, std::vector<uint32_t>{1});
}

}  // namespace
}  // namespace rephoto::render
