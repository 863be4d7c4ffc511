// Error projection (paper Section 3.1 end, Fig. 4e; Section 5.2, Fig. 9-12): the per-pixel error
// images of the evaluation views are projected back onto the reconstructed model, averaged per
// vertex (or point), normalized between two percentiles and coloured with the jet map, so that
// defects can be seen where they are on the model.
//
// Visibility. A vertex V (world position, model units) is seen by a view when all hold:
//   1. V lies in front of the camera: its camera-frame depth z = (cam_from_world * V).z > 0;
//   2. it projects inside the image: p = Camera::ImgFromCam(V_cam) (with the camera's own
//      distortion, pixel-corner convention) has 0 <= p.x < width and 0 <= p.y < height, and the
//      renderer's viewing ray through p points back at V within one pixel (this rejects points
//      outside the usable field of view of a distorted camera, where ImgFromCam folds over);
//   3. its depth agrees with the model's own depth map at the pixel containing p, P =
//      (floor(p.x), floor(p.y)): the depth d(P) rendered by the built-in renderer
//      (render/render.h, one sample per pixel at the pixel centre, camera-frame z; or the
//      ProjectView's depth_image, the nearest of the error rendering's samples, which lies
//      within the same pixel and so within the same bound below) is finite and
//      |z - d(P)| <= Tolerance(z), with
//          Tolerance(z) = depth_tolerance * z + footprint_tolerance * z / f  (+ r for points)
//      where f is the camera's mean focal length in pixels (so z / f is the size of one pixel on
//      a fronto-parallel surface at depth z) and r is the point's splat radius (point clouds only,
//      RenderModel::point_radii: neighbouring discs overlap the point's own disc). Between V
//      and the centre of P (at most 0.71 px away) the depth of a surface inclined at angle theta
//      to the image plane changes by up to 0.71 * tan(theta) footprints; the defaults (1 % of z
//      plus 2 footprints) allow 0.01 f + 2 footprints, e.g. 8.4 at f = 640 px: slopes up to
//      about 85 degrees pass. A surface closer than the tolerance hides V (occlusion); a
//      surface farther away at P means V is at a silhouette and the pixel shows something else,
//      so V is not seen there either. Occluders within the tolerance in front of V (contact
//      regions, e.g. ground just under an object) cannot be told apart at this resolution. On
//      the demo scene this test agrees with exact ray casting on 99.9 % of the (vertex, view)
//      pairs that are clearly visible and 100 % of those clearly hidden (project_demo_test).
// Error sample. The error image (1 channel, NaN = not evaluated) is interpolated bilinearly at
// p over the 4 pixel centres around p (the pixels whose centres are the corners of the cell
// containing p), using only those pixels that lie inside the image, whose error is finite and
// whose rendered depth passes the same test; the bilinear weights of the remaining pixels are
// renormalized. The pixel containing p always has weight >= 1/4, so a seen vertex whose
// containing pixel has a finite error always gets a value; when no pixel qualifies the view
// contributes nothing to that vertex (NaN error pixels are ignored, never treated as 0).
// Per vertex. vertex_error = the plain mean over the views that see it and gave it a finite
// sample (each view weighs 1, as in the paper: "multiple error images projected to the same
// location are averaged"); view_count = the number of those views. Sums are in double; views
// are accumulated in the order given, vertices in parallel with each vertex owned by one task,
// so the result is bit-for-bit independent of the thread count.
// Per face (meshes). A vertex samples the error only where it lies, so on a coarse mesh a
// viewer interpolating its vertices' colours smears a few samples across large triangles
// (streaks). Each face therefore also gets its own error: per view, a face whose longest edge
// spans 4 pixels or more (edge length * focal length / depth of its centroid) has its 4 sample
// points (the centroids of the 4 triangles of its midpoint subdivision, barycentric
// (1/3, 1/3, 1/3), (2/3, 1/6, 1/6) and its permutations) sampled exactly like vertices (same
// visibility test, bilinear sample); a smaller face takes its corners' samples of that view
// (bilinear samples at most 4 pixels apart describe it; no extra cost, so dense meshes pay
// little for their face errors); the view's value is
// the mean over the points that gave one; the face's error is the plain mean over the views
// that gave a value (face_error; NaN = none).
// WriteProjectedPly writes it as the faces' colour and error (MeshLab: Render > Color > Per
// Face shows it without streaks).
// Colours. low and high are the low_percentile and high_percentile percentiles (linear
// interpolation between order statistics, numpy's default, see core/stats.h) of the finite
// vertex errors (each vertex counts once, whatever its view count), unless a fixed range is
// given. A vertex's colour is JetColor(t) (core/colormap.h), t = (error - low) / (high - low)
// clamped to [0,1] (t = 0 when high == low, e.g. all errors equal), so low and below are dark
// blue, high and above dark red (with low > high the map runs the other way). For error images
// where higher is better (ssim) set higher_is_better (or pass a reversed fixed_range) to keep
// red = bad. Unseen vertices are grey (128, 128, 128).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "rephoto/camera/camera.h"
#include "rephoto/mesh/mesh.h"
#include "rephoto/render/render_model.h"
#include "rephoto/scene/scene.h"
#include "rephoto/splat/gaussians.h"
#include "rephoto/splat/rasterize.h"

namespace rephoto::project {

struct ProjectOptions {
  // Percentiles, in percent (0..100, low <= high), of the finite vertex errors that map to the
  // ends of the colour map.
  double low_percentile = 2.5;
  double high_percentile = 97.5;
  // Colour range [low, high] in error units used instead of the percentiles (e.g. the same
  // range for several models so their colours compare); low > high reverses the map.
  std::optional<std::pair<float, float>> fixed_range;
  // The error image holds a similarity (higher = better, e.g. ssim; see
  // compare::ErrorColourRange, whose low > high marks such metrics): the percentile range is
  // reversed (result.low = the high percentile, result.high = the low one) so that red still
  // means bad. Not applied to fixed_range, which is taken as given.
  bool higher_is_better = false;
  // Depth agreement, see the file comment: relative to the depth (0.01 = 1 % of z) ...
  double depth_tolerance = 0.01;
  // ... plus this many pixel footprints z / f.
  double footprint_tolerance = 2.0;
  // An error image whose size differs from its camera's is an Error, unless this is set and
  // only the resolution differs (aspect ratios within 1 %, e.g. an evaluation at reduced
  // resolution): then the camera is scaled to the image (Camera::Scaled).
  bool scale_cameras = false;
  // Render the back sides of triangles in the depth maps (as render::RenderOptions::backfaces;
  // use the setting the error images were rendered with).
  bool backfaces = true;
  // How the Mesh overload of ProjectErrors builds its render model: the splat radii of point
  // clouds must match the rendering the errors come from (point_radius, neighbours, scale, cap).
  // Textures are never loaded (only depth is rendered).
  render::ModelOptions model_options;
  // Per-face errors of meshes (ProjectResult::face_error, see "Per face" above); false skips
  // them.
  bool face_errors = true;
  bool show_progress = false;  // a Progress line per view
};

struct ProjectView {
  camera::Camera camera;  // intrinsics; width x height must equal the error image's size
  camera::Pose cam_from_world;
  std::filesystem::path
      error_image;   // 1-channel float EXR (any io::ReadImage format), NaN = not evaluated
  std::string name;  // for messages and progress ("fold_00/view_003"); may be empty
  // Optional: the depth map of the very rendering the errors were computed from (1-channel
  // camera-frame z per pixel, NaN = no surface; the same size as the error image), e.g.
  // `rephoto evaluate`'s renders/<view>.depth.exr, which holds per pixel the nearest of the
  // rendering's samples. Used instead of rendering the model, so it must be a rendering of this
  // model at this view. Empty: the model is rendered (one sample at each pixel centre).
  std::filesystem::path depth_image;
};

struct ProjectResult {
  // One entry per model vertex (point), in the model's vertex order.
  std::vector<float> vertex_error;   // mean error over the views counted in view_count; NaN if 0
  std::vector<uint32_t> view_count;  // views that see the vertex and gave a finite sample
  // Meshes: one entry per face (see "Per face" above), NaN where no view gave a value; empty
  // for point clouds (and for results built by hand, which WriteProjectedPly accepts).
  std::vector<float> face_error;
  float low = 0;                     // colour range used: error `low` maps to t = 0 (dark blue) ...
  float high = 0;            // ... `high` to t = 1 (dark red); NaN both when no vertex has an error
  size_t seen_vertices = 0;  // vertices with a finite vertex_error (view_count > 0)
  size_t visible_vertices = 0;  // vertices passing the visibility test in >= 1 view (with or
                                // without a finite error sample there)
  std::vector<size_t> view_seen_vertices;  // per input view: vertices it gave a sample to
  double render_seconds = 0;               // wall time rendering depth maps
  double project_seconds = 0;              // wall time reading error images and projecting vertices
};

// Projects the error images of `views` onto `model` (see the file comment). Every error image's
// header is checked before any work: it must exist, have 1 channel and the size of its camera
// (see scale_cameras), else Error "<error image>: image is WxH but its camera is wxh" (or the
// reader's message).
// Throws Error when the model has no vertices or is invalid (Mesh::Validate), when a camera or
// pose is invalid, or when the options are out of range. An empty `views` gives all-NaN errors.
ProjectResult ProjectErrors(const mesh::Mesh& model, const std::vector<ProjectView>& views,
                            const ProjectOptions& options);

// The same with a render model built by the caller (e.g. the one the views were rendered with,
// which saves building the BVH again); options.model_options is ignored. Its mesh's vertices
// are the ones projected onto.
ProjectResult ProjectErrors(const render::RenderModel& model, const std::vector<ProjectView>& views,
                            const ProjectOptions& options);

// 3D Gaussian splatting models (splat/gaussians.h): per Gaussian, the mean error of the views'
// error images weighted by the Gaussian's blending weight alpha * T at each pixel
// (splat::AccumulateGaussianErrors; pixels whose error is NaN count for nothing), NaN for a
// Gaussian no view saw; `seen` (optional) receives how many were seen. Each error image must
// have 1 channel and its camera's size, or only another resolution with
// project_options.scale_cameras (Error naming it otherwise; the other ProjectOptions do not
// apply). The Gaussians are rendered with `options` (mode, background), as they were for the
// errors. Write the result with splat::WriteGaussiansWithScalar (every property of the model's
// file kept, "error" added).
std::vector<float> ProjectErrorsOntoGaussians(const splat::GaussianModel& model,
                                              const std::vector<ProjectView>& views,
                                              const splat::GaussianRenderOptions& options,
                                              const ProjectOptions& project_options,
                                              size_t* seen = nullptr);

// The colour (8-bit RGB) of one error value for the range [low, high] (see the file comment);
// NaN gives the unseen grey.
std::array<uint8_t, 3> ErrorColour(float error, float low, float high);

// Writes the projection as a binary little-endian PLY, atomically:
//   vertex: float x y z; float nx ny nz (only when the model has normals); uchar red green blue
//           (ErrorColour of the vertex's error over [result.low, result.high]; unseen vertices
//           grey 128); float error (NaN where unseen); float quality (the same value, the
//           name MeshLab reads as vertex quality for its quality filters and histogram);
//           uint views (view_count).
//   face:   list uchar int vertex_indices (only when the model has faces); when the result
//           has face_error: uchar red green blue (ErrorColour of the face's error) and float
//           error, float quality (the face's error, NaN where no view gave one).
// Comments record the range and the number of seen vertices. Opens in MeshLab (colours;
// "quality" as vertex quality) and CloudCompare (colours; "error", "quality" and "views" as
// scalar fields). Throws Error naming `out` when the result does not belong to the model (sizes
// differ) or the file cannot be written.
void WriteProjectedPly(const mesh::Mesh& model, const ProjectResult& result,
                       const std::filesystem::path& out);

// Finds the error images of `metric` ("1-ncc", ...) for the views of `scene` in a run
// directory:
//   `rephoto evaluate`: RUN/folds/<fold>/errors/<stem>.<metric>.exr, folds in name order;
//   `rephoto compare`:  RUN/errors/<stem>.<metric>.exr.
// <stem> is the view name's file name without extension ("images/IMG_1.JPG" -> "IMG_1") when
// these are unique within the scene, else (two views share a file name in different folders)
// the relative path without extension for every view ("images/IMG_1"), as `rephoto evaluate`
// names its outputs. Returns one ProjectView per error image found, folds outer and scene views
// inner (scene order); a view evaluated in
// several folds appears once per fold (each fold's evaluation counts as one view), named
// "<fold>/<stem>" (evaluate) or "<stem>" (compare). `views_without_errors` (optional) receives
// the number of scene views without any error image; `unmatched_images` (optional) the number
// of error images of `metric` that belong to no scene view (a run of another scene). Throws
// Error "<run_dir>: ..." when the folder does not exist or has neither layout.
std::vector<ProjectView> FindErrorImages(const scene::Scene& scene,
                                         const std::filesystem::path& run_dir,
                                         std::string_view metric, size_t* views_without_errors,
                                         size_t* unmatched_images = nullptr);

// The metric names that have error images ("<stem>.<metric>.exr") in the run directory's
// errors folders, sorted; for messages such as "no error images for 'ncc' (available: 1-ncc,
// dssim)". Empty when the folder has neither layout.
std::vector<std::string> ListErrorMetrics(const std::filesystem::path& run_dir);

}  // namespace rephoto::project
