// Does camera C see point V? The one rule of colorize (render/colorize.h), texture view
// selection (texture/view_selection.h), next-view suggestions (suggest/next_views.h) and error
// projection (project/project.h). V is seen when
//   1. it lies in the camera's usable field (camera::UsableField: in front of the camera, where
//      the lens model is one-to-one; strong distortion folds points from outside the field of
//      view back into the picture);
//   2. it projects inside the image, at least `border_pixels` from its edges (pixel-corner
//      convention; 0.5 keeps bilinear sampling inside);
//   3. it faces the camera: n . (C - V) / |C - V| > min_facing_cosine, n the unit surface normal
//      at V (a point without a normal passes);
//   4. nothing hides it: an Embree occlusion ray from C towards V meets no surface before
//      (1 - occlusion_epsilon) |V - C| (OcclusionBatch; relative, so independent of the units).
//      Error projection, which has each view's rendered depth map, makes this test against the
//      depth instead (project.h).
// Steps 1-3 are Sighting(); step 4 is OcclusionBatch.
//
// Thread safety: Sighting and VisibilityRule are pure; an OcclusionBatch belongs to one thread
// (Embree queries on a committed scene are thread-safe, so one per thread).
#pragma once

#include <embree3/rtcore.h>

#include <Eigen/Core>
#include <cstdint>
#include <optional>

#include "rephoto/camera/cam_to_image.h"
#include "rephoto/camera/camera.h"

namespace rephoto::render {

struct VisibilityRule {
  // Step 3. The default rejects views within 3 degrees of grazing, whose samples smear a pixel
  // over a long strip of surface.
  double min_facing_cosine = 0.05;
  // Step 2.
  double border_pixels = 0.5;
  // Step 4: the part of the way to V (relative) where occluders no longer count (V's own
  // surface and its neighbours).
  double occlusion_epsilon = 1e-3;
};

// One camera at one pose, as the visibility tests use it.
struct ViewGeometry {
  ViewGeometry(const camera::Camera& camera, const camera::Pose& cam_from_world);
  // With the camera's usable field already made (it costs a few ms: make it once for many poses
  // of one camera).
  ViewGeometry(const camera::Camera& camera, const camera::Pose& cam_from_world,
               const camera::UsableField& field);
  camera::Camera camera;
  camera::Pose cam_from_world;
  camera::UsableField field;
  camera::CamToImage to_image;  // camera.ImgFromCam
  Eigen::Vector3d center;       // camera centre in world coordinates
};

// Where V is seen (steps 1-3 passed).
struct SightingResult {
  Eigen::Vector2d pixel;  // projection, pixel-corner convention
  double cosine = 1;      // facing cosine (1 without a normal)
  double distance = 0;    // |V - C|
};

// Steps 1-3 for point V (world coordinates) with unit normal `normal` (zero: no normal).
std::optional<SightingResult> Sighting(const ViewGeometry& view, const Eigen::Vector3d& point,
                                       const Eigen::Vector3d& normal, const VisibilityRule& rule);

// Step 1 and the projection: V's pixel when V lies in the usable field (possibly outside the
// image), else nullopt.
// `in_cam` (optional) receives V in camera coordinates.
// Inline: the error projection calls it for every vertex of every view.
[[gnu::always_inline]] inline std::optional<Eigen::Vector2d> ProjectInField(
    const ViewGeometry& view, const Eigen::Vector3d& point, Eigen::Vector3d* in_cam = nullptr) {
  const Eigen::Vector3d cam = view.cam_from_world.CamFromWorld(point);
  if (in_cam != nullptr) *in_cam = cam;
  if (!view.field.Contains(cam)) return std::nullopt;
  return view.to_image(cam);
}

// Step 2 for a pixel.
bool InsideImage(const camera::Camera& camera, const Eigen::Vector2d& pixel, double border_pixels);

// Steps 1-2 only (a point with no normal of its own, e.g. a face corner).
std::optional<Eigen::Vector2d> UsableProjection(const ViewGeometry& view,
                                                const Eigen::Vector3d& point, double border_pixels);

// Step 4 for many points seen from one camera centre, 16 occlusion rays at a time (neighbouring
// points make coherent packets). Add() queues a point with a caller's tag; when 16 are queued,
// and at Flush(), the batch is traced and `visit(tag)` is called for each queued point that
// nothing hides, in the order they were added.
class OcclusionBatch {
 public:
  OcclusionBatch(RTCScene scene, const Eigen::Vector3d& center, double occlusion_epsilon);

  template <typename Visit>
  void Add(const Eigen::Vector3d& point, uint32_t tag, Visit&& visit) {
    Queue(point, tag);
    if (count_ == kWidth) Flush(visit);
  }
  template <typename Visit>
  void Flush(Visit&& visit) {
    if (count_ == 0) return;
    Trace();
    for (int k = 0; k < count_; ++k) {
      if (packet_.tfar[k] >= 0) visit(tags_[k]);
    }
    count_ = 0;
  }

 private:
  static constexpr int kWidth = 16;
  void Queue(const Eigen::Vector3d& point, uint32_t tag);
  void Trace();

  RTCScene scene_;
  RTCIntersectContext context_;
  Eigen::Vector3d center_;
  float tfar_;
  alignas(64) RTCRay16 packet_;
  alignas(64) int valid_[kWidth];
  uint32_t tags_[kWidth];
  int count_ = 0;
};

}  // namespace rephoto::render
