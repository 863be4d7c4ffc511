#include "rephoto/render/visibility.h"

#include <cmath>
#include <limits>

namespace rephoto::render {

ViewGeometry::ViewGeometry(const camera::Camera& camera_in, const camera::Pose& pose)
    : ViewGeometry(camera_in, pose, camera::UsableField(camera_in)) {}

ViewGeometry::ViewGeometry(const camera::Camera& camera_in, const camera::Pose& pose,
                           const camera::UsableField& field_in)
    : camera(camera_in),
      cam_from_world(pose),
      field(field_in),
      to_image(camera_in),
      center(pose.Center()) {}

bool InsideImage(const camera::Camera& camera, const Eigen::Vector2d& pixel, double border_pixels) {
  const double x = pixel.x(), y = pixel.y();
  return x >= border_pixels && x <= camera.width - border_pixels && y >= border_pixels &&
         y <= camera.height - border_pixels;
}

std::optional<Eigen::Vector2d> UsableProjection(const ViewGeometry& view,
                                                const Eigen::Vector3d& point,
                                                double border_pixels) {
  const std::optional<Eigen::Vector2d> pixel = ProjectInField(view, point);
  if (!pixel || !InsideImage(view.camera, *pixel, border_pixels)) return std::nullopt;
  return pixel;
}

std::optional<SightingResult> Sighting(const ViewGeometry& view, const Eigen::Vector3d& point,
                                       const Eigen::Vector3d& normal, const VisibilityRule& rule) {
  const Eigen::Vector3d to_camera = view.center - point;
  SightingResult result;
  result.distance = to_camera.norm();
  if (!(result.distance > 0)) return std::nullopt;
  const double normal_length = normal.norm();
  if (normal_length > 0) {
    result.cosine = normal.dot(to_camera) / (normal_length * result.distance);
    if (!(result.cosine > rule.min_facing_cosine)) return std::nullopt;
  }
  const std::optional<Eigen::Vector2d> pixel = UsableProjection(view, point, rule.border_pixels);
  if (!pixel) return std::nullopt;
  result.pixel = *pixel;
  return result;
}

OcclusionBatch::OcclusionBatch(RTCScene scene, const Eigen::Vector3d& center,
                               double occlusion_epsilon)
    : scene_(scene), center_(center), tfar_(static_cast<float>(1.0 - occlusion_epsilon)) {
  rtcInitIntersectContext(&context_);
  for (int k = 0; k < kWidth; ++k) {
    packet_.org_x[k] = static_cast<float>(center.x());
    packet_.org_y[k] = static_cast<float>(center.y());
    packet_.org_z[k] = static_cast<float>(center.z());
    packet_.tnear[k] = 0.0f;
    packet_.mask[k] = 0xFFFFFFFFu;
    packet_.time[k] = 0.0f;
    packet_.flags[k] = 0;
    packet_.id[k] = static_cast<unsigned>(k);
  }
}

void OcclusionBatch::Queue(const Eigen::Vector3d& point, uint32_t tag) {
  const Eigen::Vector3d direction = point - center_;  // t = 1 at the point
  packet_.dir_x[count_] = static_cast<float>(direction.x());
  packet_.dir_y[count_] = static_cast<float>(direction.y());
  packet_.dir_z[count_] = static_cast<float>(direction.z());
  packet_.tfar[count_] = tfar_;
  valid_[count_] = -1;
  tags_[count_] = tag;
  ++count_;
}

void OcclusionBatch::Trace() {
  // Unused lanes: invalid, and tfar < tnear for Embree's ray-stream fallback (no native 16-ray
  // kernel on AVX2/SSE), which ignores the valid mask.
  for (int k = count_; k < kWidth; ++k) {
    valid_[k] = 0;
    packet_.tfar[k] = -std::numeric_limits<float>::infinity();
  }
  rtcOccluded16(valid_, scene_, &context_, &packet_);
}

}  // namespace rephoto::render
