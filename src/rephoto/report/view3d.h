// The reports' interactive 3D view (paper Fig. 5 and 9, Section 5.2): the model coloured by
// the rephotography error projected onto it, the photos' cameras as frusta and the suggested
// next views, inside one self-contained HTML file (no network at view time).
//
// What the view shows
//   - The model: a mesh (triangles) or a point cloud (points; Gaussian splatting models as
//     points at their means), coloured in one of three modes (buttons):
//       error   the projected error (project/project.h, the PLY's "error" property) through
//               the jet map of core/colormap.h over the same [low, high] range as the PLY's
//               colours (the 2.5/97.5 % percentiles unless fixed), with its colour bar and the
//               metric's name; grey = seen by no evaluation view. The map is applied per pixel
//               to the error interpolated across each triangle (not to interpolated colours),
//               so a coarse mesh shows the linear interpolation of its vertices' errors in the
//               map's own colours: no streaks of colours the map does not have. Unlit, so a
//               pixel's colour is exactly the map's colour of the error there.
//       model   the model's own vertex colours when the report could read them (shaded grey
//               otherwise), with a headlight;
//       unseen  surface seen by no photo (no view gave it an error sample, or for `suggest`,
//               no photo sees it) in magenta, the rest light grey, with a headlight.
//     An unseen vertex of a triangle whose other vertices were seen takes the mean error of its
//     seen neighbours for the interpolation, and the fragments nearer to it than to a seen
//     vertex are grey.
//   - Cameras: one frustum per photo (apex at the camera centre, image rectangle at a depth of
//     6 % of the model's bounding-box diagonal). A fold selector: "all folds" colours each
//     photo by the fold in which it was an evaluation (test) photo (training-only photos grey);
//     one fold colours its evaluation photos orange and training photos blue. Suggested views
//     (rephoto suggest) are thick magenta frusta.
//   - Orbit (left drag), zoom (wheel), pan (right drag) with three.js's OrbitControls.
//   - Clicking a frustum (within 12 px of its apex or a corner of its image rectangle on
//     screen) shows the photo's name, role, fold, its error and its photo, rephoto and error
//     thumbnails when the report embedded them. Clicking the surface shows the error there
//     and lists the views that see that point (in front of the camera, inside its image,
//     facing it and not hidden by the model: a ray cast from the camera centre) with their
//     image errors.
//
// Data. Large arrays are little-endian typed arrays in base64 inside a JSON element
// <script type="application/json">: positions float32 xyz, triangle indices uint32, errors
// float32 (NaN = not seen), colours uint8 RGB; the cameras' thumbnails are stored once per view
// (an "images" table; cameras refer to entries by index); an array equal to an earlier model's of the same
// view (runs of one mesh) refers to it instead of repeating it. Meshes above `max_faces`
// triangles are simplified for the browser by vertex clustering (meshoptimizer's
// meshopt_simplifySloppy: even triangles, no slivers across flat regions; it keeps a subset
// of the original vertices); each kept vertex then carries the mean projected error of the
// original vertices nearest to it (the error averaged over the surface it stands for, not one
// noisy sample that long triangles would smear) and its own colour. Point clouds above
// `max_points` keep every k-th point. Per model about 29 bytes of
// HTML per triangle (positions, indices, errors, colours in base64: 4/3 x (19 bytes per vertex
// + 12 per triangle), about half as many vertices as triangles): 4.3 MB at the run report's
// 150 000 triangles, 1.7 MB at the comparison report's 60 000 (ReportOptions/
// CollectionOptions::view3d_limits). HTML parsing dominates the page's load time (about 0.15 s
// per MB in headless Chromium on the shared 2-core machine).
//
// Page hooks for tests and other pages: after drawing, the view's element gets
// data-ready="1", and window.rephotoView.views[<id>] holds {three, camera, canvas, render(),
// viewProjection() (column-major 4x4 of projection * view), frusta (per shown frustum: name,
// role, apex and corners in world coordinates), select(model index), setMode(mode),
// info (the info panel element)}.
//
// Reuse: any page embeds a view with View3dHtml (one call per view, each its own element id)
// and View3dScripts once before </body> (the live page of issue 31 can do the same).
//
// Thread safety: reentrant (the loaders read the files named; the rest are pure functions).
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "rephoto/camera/camera.h"
#include "rephoto/run/run_data.h"

namespace rephoto::report {

struct View3dCamera {
  std::string name;
  // "photo" (a scene photo: test/train per fold below) or "suggested".
  std::string role = "photo";
  int test_fold = -1;               // index into View3dModel::folds where it was evaluated
  std::vector<int> train_folds;     // folds it trained
  double fx = 0, fy = 0, cx = 0, cy = 0;  // pinhole part of the intrinsics, pixels
  int width = 0, height = 0;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  // cam_from_world, x_cam = R x + t
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  double error = NAN;  // the photo's image error (primary metric), NaN = none
  std::string note;    // one line shown when selected (e.g. "sees 12 % of the unseen surface")
  std::string photo_uri, rephoto_uri, error_uri;  // data URIs of thumbnails ("" = none)
};

// A camera of the view from a scene camera and its cam_from_world pose (name and role as above;
// folds, error, note and thumbnails left empty).
View3dCamera MakeView3dCamera(const camera::Camera& intrinsics, const Eigen::Matrix3d& rotation,
                              const Eigen::Vector3d& translation, std::string name,
                              std::string role = "photo");

struct View3dModel {
  std::string label;                  // run name; shown in the selector
  std::string metric;                 // e.g. "1-ncc"
  float low = NAN, high = NAN;        // colour range (error low = dark blue, high = dark red)
  std::vector<Eigen::Vector3f> positions;
  std::vector<std::array<uint32_t, 3>> faces;  // empty = point cloud
  std::vector<float> error;                    // per vertex, NaN = not seen; empty = none
  std::vector<std::array<uint8_t, 3>> colors;  // per vertex model colours; empty = none
  std::vector<uint8_t> unseen;  // per vertex 1 = no photo sees it; empty = error is NaN
  size_t original_vertices = 0, original_faces = 0;  // before simplification
  std::vector<std::string> folds;                    // fold names, for the selector
  std::vector<View3dCamera> cameras;
  std::string note;  // one line under the view (e.g. why the model colours are missing)
};

struct View3dData {
  std::vector<View3dModel> models;          // selectable (one per run); at least one
  std::vector<View3dCamera> suggested;      // shown with every model
  std::string title;                        // heading inside the view ("" = none)
  std::string mode = "error";               // colour mode shown first: error, model, unseen
};

struct View3dLimits {
  size_t max_faces = 150000;
  size_t max_points = 200000;
};

// Simplifies the model in place to the limits (see the file comment); per-vertex arrays
// follow the kept vertices.
void DecimateForBrowser(View3dModel& model, const View3dLimits& limits = {});

// The projected errors of a run: RUN/projected/<metric>.ply (a mesh or point cloud written by
// project::WriteProjectedPly, or a Gaussian model with an "error" property, shown as points),
// decimated; the colour range from the PLY's comment ("colour range (jet) low L high H"),
// else the 2.5/97.5 % percentiles of the errors (Gaussians). Model colours from the run's
// model (run.json inputs.model.path) when run.Readable allows it (inside RUN or the folders
// the user named). Cameras: the run's split (RUN/split/<fold>/{train,test}/sparse, COLMAP
// text), each photo once with its fold roles; image errors of metric `metric` from
// per_image.csv; thumbnails of evaluated photos `thumbnail_width` wide (0 = none).
// std::nullopt when the run has no projected PLY of that metric (nothing to show); throws
// Error naming the file when it exists but cannot be read.
std::optional<View3dModel> LoadRunView3d(const run::RunData& run, const std::string& metric,
                                         int thumbnail_width, const View3dLimits& limits = {});

// All the models a run has projected errors on: LoadRunView3d's one, else (runs with
// --reconstruct: one model per fold) each RUN/projected/fold_XX.<metric>.ply, in fold order,
// labelled "fold_XX" (without model colours). Empty when there is none.
std::vector<View3dModel> LoadRunView3dModels(const run::RunData& run, const std::string& metric,
                                             int thumbnail_width, const View3dLimits& limits = {});

// The suggested views of a `rephoto suggest` folder: DIR/suggestions.json (names, poses) and
// DIR/sparse (intrinsics). Empty when DIR has no suggestions.json; Error naming the file when
// it is malformed.
std::vector<View3dCamera> LoadSuggestedCameras(const std::filesystem::path& dir);

// The view's element (<div class="view3d" id="`id`"> with its controls, canvas, colour bar,
// info panel and the data as JSON). `id` must be unique in the page ([A-Za-z0-9_-]).
std::string View3dHtml(const View3dData& data, const std::string& id);

// The scripts (three.js, OrbitControls, the view) and CSS, once per page after every view's
// element (e.g. just before </body>).
std::string View3dScripts();

}  // namespace rephoto::report
