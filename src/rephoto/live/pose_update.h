// Poses refined by the registration engine after photos joined (COLMAP's bundle adjustment:
// the local one of image_registrator around each new photo, or a global bundle_adjuster),
// taken over by the live session (live_session.h).
//
// A bundle adjustment has a free gauge: it may move, turn and scale the whole frame, and it
// refines each photo's pose relative to the others. The two are told apart by the similarity
// X' = s R X + t that best maps the photos' old camera centres onto their new ones (least
// squares, Umeyama 1991; with fewer than 3 photos, or centres on a line, only the scale about
// their centroids and the translation), fitted again on the photos it carries within the
// thresholds below (at most 3 rounds, while at least 3 remain), so that one refined photo does
// not tilt the fit and make its neighbours look refined:
//   - the frame's move (the similarity) keeps every plane-sweep depth map valid up to its scale:
//     depth is camera-frame z, so it is multiplied by s (exact for a similarity);
//   - what remains per photo (its new centre's distance from s R c + t, relative to the new
//     centres' RMS distance from their centroid, and the angle between its new rotation and
//     its old one carried by the similarity, R_old R^T) is a refinement of that photo against
//     the others: above `move_fraction` or `rotate_degrees` its depth map, estimated with the
//     old relative poses, is estimated again.
// Units: the photos' world frame; angles in degrees. Thread safety: reentrant.
#pragma once

#include <vector>

#include "rephoto/camera/camera.h"

namespace rephoto::live {

struct PoseUpdateOptions {
  double move_fraction = 0.01;  // of the new centres' RMS distance from their centroid
  double rotate_degrees = 0.5;
  // A photo's intrinsics refined by more than this (IntrinsicsChange) change its depth as much
  // as a pose refinement does: its depth map is estimated again too.
  double intrinsics_fraction = 0.005;
};

struct PoseChange {
  double scale = 1;             // s of the frame's similarity (the same for every photo)
  double moved = 0;             // residual centre move / RMS spread of the new centres
  double rotated_degrees = 0;   // residual rotation
  bool refresh_depth = false;   // moved or rotated beyond the options
};

// before[i] and after[i] are the same photo's pose (cam_from_world) before and after the
// refinement. Returns one PoseChange per photo. Throws Error when the sizes differ.
std::vector<PoseChange> ComparePoses(const std::vector<camera::Pose>& before,
                                     const std::vector<camera::Pose>& after,
                                     const PoseUpdateOptions& options = {});

// How much a camera's intrinsics changed: the largest relative change of a parameter (relative
// to max(1, |before|): focal lengths and principal points in pixels, distortion unitless);
// 1 when the model, the size or the parameter count differ.
double IntrinsicsChange(const camera::Camera& before, const camera::Camera& after);

}  // namespace rephoto::live
