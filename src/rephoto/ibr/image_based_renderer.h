// Image-based representations (paper Section 5.1): render a novel view directly from the
// training photos, with a global mesh as geometry proxy (view-dependent texturing, VDT) or with
// one depth map per training photo (image-based rendering, IBR).
//
// Both share one per-pixel fusion (the unstructured lumigraph of Buehler et al. 2001 with a
// weighted per-channel median, as the paper's implementation):
// 1. Novel-view geometry: each pixel's surface point X (at the pixel centre, one sample per
//    pixel) and its camera-frame depth z.
//    - VDT: the proxy mesh ray-cast with Embree (render::RenderRephoto).
//    - IBR: every training depth map is turned into a mesh (a grid of its pixels every
//      `proxy_grid_spacing` photo pixels, unprojected once at construction; triangles that
//      their own camera sees at less than `proxy_edge_angle` degrees from edge-on are cut: they
//      join a foreground to a background across an occlusion edge). The meshes of the
//      3 * k_best training views nearest to the novel view (ranked as in step 2, at the
//      training views' median depth) are forward-warped into the novel view by rasterization
//      (perspective-correct 1/z interpolation; the novel camera's distortion applied at the
//      vertices). Each pixel keeps the 4 nearest surfaces of different training views; its
//      depth is the nearest one that a second view confirms within `depth_tolerance`
//      (relative), else the nearest one (so that one view's stereo outlier does not occlude
//      the others).
// 2. Candidate views: the training views nearest to the novel view (by the angle between
//    their camera centres seen from the novel view's central scene point, at most 32 views).
//    X is projected into each (its own camera, distortion and resolution). A view is a
//    candidate when X lies inside its photo (at least half a pixel from the border) and is
//    visible there: the training view's depth map (VDT: the proxy rendered at that view at
//    construction; IBR: its own depth map), interpolated at the projection (1/z bilinear
//    between the four surrounding depth pixels, or the nearest one when some have no depth),
//    agrees with X's depth z_i in that view: |D - z_i| <= depth_tolerance * z_i. The colour is
//    sampled bilinearly from the photo (the nearest photo pixel where the depth was taken from
//    the nearest depth pixel, so colours do not bleed across depth-map holes).
// 3. Penalty of candidate i: p_i = a_i + depth_penalty * e_i with a_i the angle (radians)
//    between the rays from X to the training camera's centre and to the novel camera's centre
//    (Buehler's angular penalty) and e_i = |D - z_i| / (depth_tolerance * z_i) in [0, 1] the
//    depth-consistency penalty (the role of the TS3 term in the paper: a view whose own
//    geometry disagrees with the rendered surface is trusted less; 0 for an exact proxy).
//    With resolution_penalty r > 0 (off by default) a third term r * max(0, log2(A_i / A)):
//    A_i is the surface area one pixel of training photo i covers at X (z_i^3 / (fx_i fy_i
//    |X - C_i| |cos t_i|), t_i the angle between the surface normal and the ray to C_i; exact
//    for pinhole cameras), A the area one novel pixel covers (|dX/dx x dX/dy| from the novel
//    depth of the neighbouring pixels, whose cross product is also the normal). A photo that
//    sees the surface at a grazing angle or from much farther away samples it coarser than the
//    novel view and is trusted less (Buehler's resolution penalty, with the surface's slant).
//    The term is left out where the novel depth has no usable neighbour in x or in y (a
//    neighbour counts when its depth is within 10 * depth_tolerance of the pixel's).
// 4. The k_best candidates with the smallest penalties are fused. Weights follow Buehler's
//    k-nearest blending, w_i = (1 - p_i / p_th) / (p_i + epipole_epsilon), p_th = the penalty
//    of the (k_best+1)-th candidate (twice the largest penalty when there are at most k_best),
//    so that the weight falls to 0 for the first view left out (no popping); the division by
//    p_i + epsilon makes a training camera that coincides with the novel camera dominate
//    (epipole consistency: it reproduces its own photo; this is why evaluation must hold
//    the test photos out of the training set). If all weights are 0, all count equally.
// 5. Colour: the weighted median of each channel separately (render/weighted_median.h).
//
// Output (render::Rephoto, like render::RenderRephoto): color RGBA, RGB = the fused colour as
// the photos store it ([0,1]), alpha = 1 where at least one training photo sees the pixel's
// surface and 0 elsewhere (RGB 0): the completeness mask; depth = the novel camera-frame z of
// the surface where alpha is 1, NaN elsewhere.
//
// Memory: photos are stored as 8-bit RGB (3 bytes per pixel: 20 photos of 1920x1080 take
// 124 MB) plus one float depth map per view (VDT: at the photo's resolution, 166 MB for the same
// 20 photos; IBR: the given/estimated depth maps) plus, for IBR, the unprojected proxy grid.
// Rendering reuses scratch buffers between calls (guarded by a mutex; concurrent Render calls
// work, the ones that find the buffers busy allocate their own).
// Thread safety: Render is const and may be called from several threads.
//
// Usage (one renderer per cross-validation fold, built from the fold's training views only):
//   std::vector<TrainingView> training = TrainingViewsFromScene(scene, fold.train, depth_dir);
//   ImageBasedRenderer vdt = ImageBasedRenderer::Vdt(proxy_mesh, training, options);
//   for (size_t t : fold.test) {
//     render::Rephoto r = vdt.Render(scene.CameraOf(scene.views[t]),
//                                    scene.views[t].cam_from_world);  // alpha = completeness
//   }
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "rephoto/camera/camera.h"
#include "rephoto/core/image.h"
#include "rephoto/ibr/plane_sweep.h"
#include "rephoto/mesh/mesh.h"
#include "rephoto/render/view_renderer.h"
#include "rephoto/render/render.h"

namespace rephoto::ibr {

struct TrainingView {
  std::string name;       // for messages
  camera::Camera camera;  // intrinsics of the photo (scaled to the photo when sizes differ)
  camera::Pose cam_from_world;
  std::filesystem::path photo;      // any format io::ReadImage reads (grey, RGB, RGBA)
  std::filesystem::path depth_map;  // optional, IBR only (depth_map_io.h); empty = estimate
  // Optional, IBR only: an in-memory depth map (depth_map_io.h convention, any resolution),
  // used instead of `depth_map` when set (callers that keep depth maps in memory, e.g. `rephoto
  // live`, need not write files).
  std::shared_ptr<const Image> depth;
};

struct ImageBasedOptions {
  int k_best = 4;                  // views fused per pixel (>= 1)
  double epipole_epsilon = 0.002;  // radians (about 0.1 degrees), > 0
  double depth_tolerance = 0.02;   // relative depth agreement for visibility (> 0)
  double depth_penalty = 0.1;      // radians of penalty for a full-tolerance depth mismatch
  double resolution_penalty = 0;   // radians per doubling of the pixel footprint (step 3); >= 0
  // IBR proxies.
  double proxy_grid_spacing = 4;  // photo pixels between proxy mesh vertices (>= 1)
  double proxy_edge_angle = 5;    // degrees; flatter proxy triangles are cut (occlusion edges)
  // IBR without depth-map files: plane-sweep stereo (plane_sweep.h) over the `sweep_neighbors`
  // neighbours of each training view chosen by SelectNeighbors. The depth range of a view,
  // unless plane_sweep.min_depth/max_depth are set, comes from `scene_points` (the 2nd and 98th
  // percentile of the depths of the points that project into the view, widened by a factor
  // 1.25 each way) or, without points, from the depth d at which the view's optical axis
  // passes closest to its neighbours' optical axes (median over the neighbours):
  // [d / 2.5, 2.5 d].
  PlaneSweepOptions plane_sweep;
  int sweep_neighbors = 4;
  // When the range is estimated (not set in plane_sweep), first sweep at a quarter of the
  // working width and narrow the range to the 2nd..98th percentile of the depths found there
  // (widened by 15 % each way), so that the planes are dense where the scene is.
  bool sweep_refine_range = true;
  // Estimated depths survive only when at least this many of the view's sweep neighbours agree
  // within depth_tolerance (FilterInconsistentDepths; 0 = keep all).
  int sweep_min_consistent = 1;
  std::vector<Eigen::Vector3d> scene_points;  // world points (e.g. a sparse model), optional
  bool show_progress = false;  // Progress lines while loading photos / estimating depth
};

class ImageBasedRenderer {
 public:
  // View-dependent texturing on `proxy` (a triangle mesh; colours are ignored). Reads every
  // training photo (errors name the file) and renders the proxy's depth at every training
  // camera. Throws Error for an empty training set, invalid options or cameras, an invalid
  // mesh or a mesh without triangles.
  static ImageBasedRenderer Vdt(const mesh::Mesh& proxy, std::vector<TrainingView> training,
                                const ImageBasedOptions& options);
  // Image-based rendering with per-view depth maps: read from TrainingView::depth_map when
  // given (depth_map_io.h; any resolution), else computed by plane-sweep stereo (needs at
  // least 2 training views). Throws Error as Vdt does and for unreadable depth maps.
  static ImageBasedRenderer Ibr(std::vector<TrainingView> training,
                                const ImageBasedOptions& options);

  ImageBasedRenderer(ImageBasedRenderer&&) noexcept;
  ImageBasedRenderer& operator=(ImageBasedRenderer&&) noexcept;
  ~ImageBasedRenderer();

  // Renders the novel view (image size camera.width x camera.height); see the output
  // convention above. Throws Error for an invalid camera or pose.
  render::Rephoto Render(const camera::Camera& camera, const camera::Pose& cam_from_world) const;
  // The same into `out`, reusing its buffers.
  void Render(const camera::Camera& camera, const camera::Pose& cam_from_world,
              render::Rephoto* out) const;

  size_t view_count() const;
  const TrainingView& view(size_t index) const;
  // The depth map used for a training view (VDT: the proxy's; IBR: read or estimated), in the
  // convention of depth_map_io.h.
  const Image& depth_map(size_t index) const;

  struct State;  // implementation (image_based_renderer.cc)

 private:
  explicit ImageBasedRenderer(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

// An ImageBasedRenderer as a render::ViewRenderer (render/view_renderer.h: RenderViews, the
// renderers of `rephoto evaluate`).
class ImageBasedViewRenderer : public render::ViewRenderer {
 public:
  explicit ImageBasedViewRenderer(ImageBasedRenderer renderer) : renderer_(std::move(renderer)) {}
  void Render(const camera::Camera& camera, const camera::Pose& cam_from_world,
              render::Rephoto* out) override {
    renderer_.Render(camera, cam_from_world, out);
  }
  const ImageBasedRenderer& renderer() const { return renderer_; }

 private:
  ImageBasedRenderer renderer_;
};

// Plane-sweep depth maps (ImageBasedOptions::plane_sweep, sweep_neighbors, scene_points,
// sweep_min_consistent) for the views with estimate[i] set, each matched against neighbours
// chosen among all `views` (SelectNeighbors), followed by the consistency filter among the
// estimated views. This is what Ibr does for training views without a depth map; `rephoto
// depth` writes its results. Returns one depth map per view (empty where estimate[i] is false)
// at the sweep's working resolution, in the convention of depth_map_io.h. Reads the photos
// (errors name the file); throws Error for fewer than 2 views or invalid options.
std::vector<Image> EstimateDepthMaps(const std::vector<TrainingView>& views,
                                     const std::vector<bool>& estimate,
                                     const ImageBasedOptions& options);

}  // namespace rephoto::ibr
