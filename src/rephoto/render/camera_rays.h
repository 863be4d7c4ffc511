// Viewing rays of a camera, precomputed once per intrinsics and reused for every view that
// shares them (the expensive part for distorted models is the iterative undistortion).
//
// A ray is returned as normalized image-plane coordinates (xn, yn): the camera-frame direction
// (xn, yn, 1), so the ray parameter t of a hit equals the camera-frame depth z.
// Pinhole models (SIMPLE_PINHOLE, PINHOLE) are computed exactly on the fly:
// xn = (px - cx) / fx. For every other model the table holds Camera::CamFromImg at the pixel
// corners, the integer positions (i, j), 0 <= i <= width, 0 <= j <= height, and a sample
// position is bilinearly interpolated from its four surrounding corners. The interpolation error
// is bounded by (1/8) * max |second derivative of the undistortion| over one pixel, below
// 1e-4 pixels for real lens distortion (checked in camera_rays_test). Where the model cannot
// unproject (beyond its usable field of view) the corner is invalid and samples touching it
// give no ray.
//
// Thread safety: a CameraRays is immutable once built; share it between threads freely.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <memory>
#include <vector>

#include "rephoto/camera/camera.h"

namespace rephoto::render {

class CameraRays {
 public:
  // Throws Error when the camera is invalid (Camera::Validate, e.g. a zero focal length).
  explicit CameraRays(const camera::Camera& camera);

  const camera::Camera& camera() const { return camera_; }
  int width() const { return camera_.width; }
  int height() const { return camera_.height; }

  // The ray through pixel position (px, py), pixel-corner convention, 0 <= px <= width,
  // 0 <= py <= height. False when the camera cannot unproject there.
  bool Ray(float px, float py, float* xn, float* yn) const {
    if (pinhole_) {
      PinholeRay(px, py, xn, yn);
      return true;
    }
    const float fx = std::floor(px), fy = std::floor(py);
    int ix = static_cast<int>(fx), iy = static_cast<int>(fy);
    ix = ix < 0 ? 0 : (ix >= camera_.width ? camera_.width - 1 : ix);
    iy = iy < 0 ? 0 : (iy >= camera_.height ? camera_.height - 1 : iy);
    const float ax = px - static_cast<float>(ix), ay = py - static_cast<float>(iy);
    const Eigen::Vector2f* c = lattice_.data() + static_cast<size_t>(iy) * stride_ + ix;
    const Eigen::Vector2f top = (1 - ax) * c[0] + ax * c[1];
    const Eigen::Vector2f bottom = (1 - ax) * c[stride_] + ax * c[stride_ + 1];
    const Eigen::Vector2f value = (1 - ay) * top + ay * bottom;
    *xn = value.x();
    *yn = value.y();
    return std::isfinite(value.x());  // NaN corners mark invalid rays
  }

  // True for pinhole models, whose rays PinholeRay computes.
  bool is_pinhole() const { return pinhole_; }
  // Ray for a pinhole model (is_pinhole()): always valid, the same values as Ray.
  [[gnu::always_inline]] void PinholeRay(float px, float py, float* xn, float* yn) const {
    *xn = (px - cx_) * inv_fx_;
    *yn = (py - cy_) * inv_fy_;
  }

  // Ray for n positions at once: (xn[i], yn[i]) = Ray(px[i], py[i]), ok[i] = 1 where it returns
  // true, else 0 (bit-identical to Ray; where ok[i] = 0, xn[i] and yn[i] are unspecified). For
  // pinhole models a branch-free loop that the compiler vectorizes (the renderer's ray
  // generation); for the table, 8 positions at a time with AVX2 on the AVX2 and AVX-512 paths
  // (the same multiplications and additions in the same order as Ray, no contraction).
  void Rays(int n, const float* px, const float* py, float* xn, float* yn, int* ok) const {
    if (pinhole_) {
      for (int i = 0; i < n; ++i) {
        PinholeRay(px[i], py[i], xn + i, yn + i);
        ok[i] = 1;
      }
      return;
    }
    TableRays(n, px, py, xn, yn, ok);
  }

 private:
  // Rays from the table (not pinhole_).
  void TableRays(int n, const float* px, const float* py, float* xn, float* yn, int* ok) const;

  camera::Camera camera_;
  bool pinhole_ = true;
  float cx_ = 0, cy_ = 0, inv_fx_ = 1, inv_fy_ = 1;
  size_t stride_ = 0;                     // width + 1
  std::vector<Eigen::Vector2f> lattice_;  // (width + 1) x (height + 1), NaN = invalid
};

// The table of `camera` from a process-wide cache of the last few intrinsics used (the same
// table CameraRays(camera) builds): objects made per photo or per update (the live session's
// envelope model, an image-based renderer per prediction) share the tables of one camera
// instead of undistorting every pixel again. A distorted camera's table is 8 bytes per pixel
// corner (16 MB at 2 MP, ~100 MB at 12 MP), so only 4 are kept. Thread-safe; throws as CameraRays
// does.
std::shared_ptr<const CameraRays> SharedCameraRays(const camera::Camera& camera);

}  // namespace rephoto::render
