// The forward projection of COLMAP's camera models with the model's lookups and checks made
// once per camera (CamToImage), for loops over many points: the error projection, visibility.
// Camera::ImgFromCam is CamToImage(camera)(point), so the two give the same values bit for
// bit (the library is built without floating-point contraction; inlining changes no result).
//
// Thread safety: CamToImage is immutable after construction.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cmath>
#include <limits>
#include <optional>

#include "rephoto/camera/camera.h"

namespace rephoto::camera {
namespace internal {

// COLMAP's additive distortion (du, dv) of the normalized (or, for fisheye models, the
// angle-scaled) coordinates (u, v); `k` points at the parameters after the principal point.
// FOV is not additive and is handled separately.
template <typename T>
inline void Distortion(CameraModel model, const double* k, const T& u, const T& v, T* du, T* dv) {
  const T u2 = u * u;
  const T v2 = v * v;
  const T uv = u * v;
  const T r2 = u2 + v2;
  switch (model) {
    case CameraModel::kSimplePinhole:
    case CameraModel::kPinhole:
    case CameraModel::kFov:
      *du = 0.0 * u;
      *dv = 0.0 * v;
      return;
    case CameraModel::kSimpleRadial:
    case CameraModel::kSimpleRadialFisheye: {
      const T radial = k[0] * r2;
      *du = u * radial;
      *dv = v * radial;
      return;
    }
    case CameraModel::kRadial:
    case CameraModel::kRadialFisheye: {
      const T radial = k[0] * r2 + k[1] * (r2 * r2);
      *du = u * radial;
      *dv = v * radial;
      return;
    }
    case CameraModel::kOpenCv: {
      const double k1 = k[0], k2 = k[1], p1 = k[2], p2 = k[3];
      const T radial = k1 * r2 + k2 * (r2 * r2);
      *du = u * radial + (2.0 * p1) * uv + p2 * (r2 + 2.0 * u2);
      *dv = v * radial + (2.0 * p2) * uv + p1 * (r2 + 2.0 * v2);
      return;
    }
    case CameraModel::kOpenCvFisheye: {
      // Here r2 is theta^2.
      const T r4 = r2 * r2;
      const T radial = k[0] * r2 + k[1] * r4 + k[2] * (r4 * r2) + k[3] * (r4 * r4);
      *du = u * radial;
      *dv = v * radial;
      return;
    }
    case CameraModel::kFullOpenCv: {
      const double k1 = k[0], k2 = k[1], p1 = k[2], p2 = k[3];
      const double k3 = k[4], k4 = k[5], k5 = k[6], k6 = k[7];
      const T r4 = r2 * r2;
      const T r6 = r4 * r2;
      const T radial =
          (1.0 + (k1 * r2 + k2 * r4 + k3 * r6)) / (1.0 + (k4 * r2 + k5 * r4 + k6 * r6));
      *du = u * radial + (2.0 * p1) * uv + p2 * (r2 + 2.0 * u2) - u;
      *dv = v * radial + (2.0 * p2) * uv + p1 * (r2 + 2.0 * v2) - v;
      return;
    }
    case CameraModel::kThinPrismFisheye: {
      const double k1 = k[0], k2 = k[1], p1 = k[2], p2 = k[3];
      const double k3 = k[4], k4 = k[5], sx1 = k[6], sy1 = k[7];
      const T r4 = r2 * r2;
      const T r6 = r4 * r2;
      const T radial = k1 * r2 + k2 * r4 + k3 * r6 + k4 * (r6 * r2);
      *du = u * radial + (2.0 * p1) * uv + p2 * (r2 + 2.0 * u2) + sx1 * r2;
      *dv = v * radial + (2.0 * p2) * uv + p1 * (r2 + 2.0 * v2) + sy1 * r2;
      return;
    }
  }
}

// FOV model (Devernay & Faugeras), COLMAP's FOVCameraModel::Distortion: the distorted
// coordinates themselves (not an offset), with its series expansions near omega = 0 and r = 0.
Eigen::Vector2d FovDistort(double omega, double u, double v);

}  // namespace internal

// Camera::ImgFromCam for one camera (see camera.h for the formulas).
class CamToImage {
 public:
  // Throws Error when `camera.params` has the wrong length for its model (as ImgFromCam).
  explicit CamToImage(const Camera& camera);

  [[gnu::always_inline]] std::optional<Eigen::Vector2d> operator()(
      const Eigen::Vector3d& point_in_cam) const {
    if (!(point_in_cam.z() >= std::numeric_limits<double>::epsilon())) return std::nullopt;
    double u = point_in_cam.x() / point_in_cam.z();
    double v = point_in_cam.y() / point_in_cam.z();
    Eigen::Vector2d distorted;
    if (model_ == CameraModel::kFov) {
      distorted = internal::FovDistort(extra_[0], u, v);
    } else {
      if (fisheye_) {
        const double r = std::sqrt(u * u + v * v);
        if (r > std::numeric_limits<double>::epsilon()) {
          const double theta_over_r = std::atan(r) / r;
          u *= theta_over_r;
          v *= theta_over_r;
        }
      }
      double du = 0, dv = 0;
      internal::Distortion(model_, extra_.data(), u, v, &du, &dv);
      distorted = {u + du, v + dv};
    }
    const Eigen::Vector2d pixel(fx_ * distorted.x() + cx_, fy_ * distorted.y() + cy_);
    if (!pixel.allFinite()) return std::nullopt;
    return pixel;
  }

 private:
  CameraModel model_;
  bool fisheye_;
  double fx_, fy_, cx_, cy_;
  std::array<double, 8> extra_{};  // the parameters after the principal point
};

}  // namespace rephoto::camera
