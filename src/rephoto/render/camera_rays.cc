#include "rephoto/render/camera_rays.h"

#include <limits>

#include "rephoto/core/parallel.h"
#include "rephoto/core/recent_cache.h"

namespace rephoto::render {

CameraRays::CameraRays(const camera::Camera& camera) : camera_(camera) {
  camera_.Validate("camera");
  pinhole_ = camera_.IsPinhole();
  const auto& p = camera_.params;
  if (camera_.model == camera::CameraModel::kSimplePinhole) {
    inv_fx_ = inv_fy_ = static_cast<float>(1.0 / p[0]);
    cx_ = static_cast<float>(p[1]);
    cy_ = static_cast<float>(p[2]);
  } else if (camera_.model == camera::CameraModel::kPinhole) {
    inv_fx_ = static_cast<float>(1.0 / p[0]);
    inv_fy_ = static_cast<float>(1.0 / p[1]);
    cx_ = static_cast<float>(p[2]);
    cy_ = static_cast<float>(p[3]);
  }
  if (pinhole_) return;
  stride_ = static_cast<size_t>(camera_.width) + 1;
  lattice_.resize(stride_ * (static_cast<size_t>(camera_.height) + 1));
  const float nan = std::numeric_limits<float>::quiet_NaN();
  ParallelFor(0, camera_.height + 1, 16, [&](int64_t begin, int64_t end) {
    for (int64_t j = begin; j < end; ++j) {
      for (size_t i = 0; i < stride_; ++i) {
        const auto ray =
            camera_.CamFromImg(Eigen::Vector2d(static_cast<double>(i), static_cast<double>(j)));
        Eigen::Vector2f& out = lattice_[static_cast<size_t>(j) * stride_ + i];
        if (ray && (*ray).z() > 1e-9) {
          out = Eigen::Vector2f(static_cast<float>(ray->x() / ray->z()),
                                static_cast<float>(ray->y() / ray->z()));
        } else {
          out = Eigen::Vector2f(nan, nan);
        }
      }
    }
  });
}

std::shared_ptr<const CameraRays> SharedCameraRays(const camera::Camera& camera) {
  static RecentCache<camera::Camera, CameraRays> cache(4);
  return cache.Get(camera, [&] { return CameraRays(camera); });
}

}  // namespace rephoto::render
