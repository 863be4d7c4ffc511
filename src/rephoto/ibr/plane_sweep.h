// Multi-view plane-sweep stereo: a depth map for one view from its neighbouring calibrated
// photos, so that image-based rendering works for a user who has only photos and cameras.
//
// Algorithm (Collins 1996; Gallup et al. 2007 with fronto-parallel planes only):
// 1. Working images: each photo is converted to grey (luma 0.299 R + 0.587 G + 0.114 B of the
//    stored values), reduced by area averaging so that its width is at most
//    PlaneSweepOptions::max_width (the camera scaled accordingly, Camera::Scaled), and
//    resampled (bilinearly) into an undistorted PINHOLE image with the same focal lengths and
//    principal point, so that every plane induces a homography between two views.
// 2. Hypotheses: `num_planes` planes parallel to the reference image plane at depths uniformly
//    spaced in inverse depth between min_depth and max_depth (the reference camera's z).
// 3. Matching cost: for each plane and neighbour, the neighbour's working image is warped into
//    the reference view through the plane's homography (bilinear; outside its image =
//    invalid) and compared with the reference by the normalized cross-correlation (NCC) of
//    window x window grey patches (window sums: constant cost per pixel). A patch touching an
//    invalid warped pixel, or whose warped side is flat (variance below min_texture^2), scores
//    -1 for that neighbour. The score of a plane is the mean of the `best_neighbors` highest
//    neighbour NCCs (occlusions affect some neighbours only).
// 4. Winner-take-all over the planes, refined by fitting a parabola through the scores of the
//    winning plane and its two neighbours (in inverse depth).
// 5. Confidence filter: a pixel keeps its depth only when its best score is >= min_ncc and
//    its reference patch has a standard deviation >= min_texture (grey values in [0,1]):
//    textureless and ambiguous pixels become NaN.
// 6. The depth map is returned in the reference's own (distorted) pixel grid at the working
//    resolution: each pixel takes the nearest undistorted estimate along its viewing ray.
// Values are camera-frame z in scene units (see depth_map_io.h for the depth-map convention).
// Work is parallel over bands of rows; the result does not depend on the thread count.
#pragma once

#include <span>
#include <vector>

#include "rephoto/camera/camera.h"
#include "rephoto/core/image.h"

namespace rephoto::ibr {

struct PlaneSweepOptions {
  int max_width = 1000;  // working width in pixels (0 = the photo's own)
  int num_planes = 96;   // depth hypotheses (>= 2)
  // Depth range of the sweep (reference camera z, scene units), 0 < min_depth < max_depth.
  double min_depth = 0;
  double max_depth = 0;
  int window = 7;          // NCC window side in working pixels (odd, >= 3)
  int best_neighbors = 2;  // neighbour scores averaged per plane (clamped to the neighbour count)
  double min_ncc = 0.5;    // confidence: minimum winning score, in [-1, 1]
  double min_texture = 0.01;  // confidence: minimum patch standard deviation (grey in [0,1])
};

// One calibrated photo. `photo` has 1, 3 or 4 channels (values in [0,1]); `camera` describes
// its pixel grid (scaled to the photo's size when they differ).
struct PlaneSweepView {
  camera::Camera camera;
  camera::Pose cam_from_world;
  const Image* photo = nullptr;
};

struct PlaneSweepResult {
  Image depth;            // 1 channel, camera-frame z, NaN where filtered out
  Image score;            // 1 channel, the winning mean NCC (NaN where nothing matched)
  camera::Camera camera;  // the reference camera scaled to the depth map's size
};

// Depth map of `reference` from `neighbors` (at least 1). Throws Error when the depth range or
// another option is invalid, a photo is missing or empty, or a camera is invalid.
PlaneSweepResult ComputePlaneSweepDepth(const PlaneSweepView& reference,
                                        std::span<const PlaneSweepView> neighbors,
                                        const PlaneSweepOptions& options);

// A depth map with the camera of its pixel grid (see depth_map_io.h), for FilterInconsistentDepths.
struct DepthView {
  camera::Camera camera;  // describes `depth`'s pixel grid (size = depth's size)
  camera::Pose cam_from_world;
  Image* depth = nullptr;  // 1 channel, camera-frame z, NaN = unknown
};

// Multi-view geometric consistency (as in COLMAP's fusion and most MVS pipelines): a depth
// pixel of views[i] survives when, for at least `min_consistent` of the views listed in
// neighbors[i], its 3D point (unprojected at the pixel centre) projects inside that view's depth
// map and the depth found there (nearest pixel) equals the point's depth in that view within
// `tolerance` (relative). Independent stereo errors rarely agree between views, so this removes
// most wrong matches. All views are tested against the unfiltered maps, then filtered. Throws
// Error when the sizes of `neighbors` and `views` differ or an index is out of range.
void FilterInconsistentDepths(std::span<const DepthView> views,
                              const std::vector<std::vector<size_t>>& neighbors, double tolerance,
                              int min_consistent);

// Picks up to `count` neighbours of views[reference] for matching: views whose viewing
// direction is within 60 degrees of the reference's and whose triangulation angle at the
// reference's scene point (the point at `scene_depth` along its optical axis) is at least
// `min_angle_degrees`, sorted by that angle (smallest first: most similar appearance). Returns
// indices into `views`.
std::vector<size_t> SelectNeighbors(std::span<const camera::Pose> views, size_t reference,
                                    double scene_depth, int count, double min_angle_degrees = 3.0);

}  // namespace rephoto::ibr
