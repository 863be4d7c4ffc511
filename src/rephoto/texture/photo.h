// A decoded photo with its camera, as the texturing stages sample it (internal to texture/).
//
// Pixel positions use rephoto's corner convention (camera/camera.h): pixel (x, y) covers
// [x, x+1) x [y, y+1), its centre is (x + 0.5, y + 0.5). 8-bit files stay 8-bit in memory
// (value v stands for v / 255); 16-bit PNG, EXR and PFM are kept as floats. Grey photos are
// replicated to RGB, alpha is ignored. Read-only after Load: safe to share across threads.
#pragma once

#include <Eigen/Core>
#include <filesystem>

#include "rephoto/camera/camera.h"
#include "rephoto/core/image.h"
#include "rephoto/scene/scene.h"

namespace rephoto::texture {

class Photo {
 public:
  // Decodes view's photo (reusing this object's buffers) and sets camera() to the view's
  // camera scaled to the decoded size (Camera::Scaled) when they differ. Throws Error naming
  // the file when it cannot be read or has no colour channels.
  void Load(const scene::Scene& scene, const scene::View& view);

  int width() const { return is8_ ? bytes_.width() : floats_.width(); }
  int height() const { return is8_ ? bytes_.height() : floats_.height(); }
  const camera::Camera& camera() const { return camera_; }
  const camera::Pose& cam_from_world() const { return cam_from_world_; }

  // RGB of pixel (x, y), 0 <= x < width, 0 <= y < height.
  Eigen::Vector3f Pixel(int x, int y) const;
  // Bilinear RGB at a continuous position; positions outside [0.5, size - 0.5] clamp to the
  // border pixels.
  Eigen::Vector3f Sample(double px, double py) const;
  // Pixel position of a world point (distortion applied); nullopt behind the camera.
  std::optional<Eigen::Vector2d> Project(const Eigen::Vector3d& world) const {
    return camera_.ImgFromCam(cam_from_world_.CamFromWorld(world));
  }

 private:
  Image8 bytes_;
  Image floats_;
  bool is8_ = false;
  camera::Camera camera_;
  camera::Pose cam_from_world_;
};

// Luma (0.299 R + 0.587 G + 0.114 B) gradient magnitude by the 3x3 Sobel operator divided by
// 8 (so a unit step between neighbouring pixels gives about 0.5), one float per pixel, into
// `out` (reused); border pixels replicate their neighbours. Parallel over rows.
void GradientMagnitude(const Photo& photo, Image* out);

}  // namespace rephoto::texture
