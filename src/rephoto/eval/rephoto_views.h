// The rephoto_views stage of `rephoto evaluate` (eval/state.h): render a fold's held-out views
// with rephoto's renderer (or take the external renderer's images), compare them with the
// photos at the evaluation resolution and write one record per view.
//
// PlanViews      for views [first, first + count) of the fold (in FoldPlan::tests order; count 0
//                = to the end), into `views` (sized to the fold's tests): each view's record key
//                and render key (keys.h); a view whose record (folds/fold_XX/views/<stem>.json)
//                holds the same key with status "ok" and whose outputs exist is reused; a view
//                whose rendering has the same render key is only compared again. Returns the
//                indices of the views that need work.
// EvaluateViews  renders (renderer, when not reused) and compares each view: the photo
//                (downscaled once into CacheDir()/eval_photos/<stem>.png with eval_short_side),
//                its mask, the rendering's coverage (Gaussians: alpha >= min_alpha, the rule
//                of compare::CompareOptions::min_alpha) through compare::ComparePhotoAndRender;
//                writes renders/<stem>.png + .depth.exr, errors/<stem>.<metric>.exr|png and the
//                view record last. A view that fails is recorded in its outcome (message) and the
//                others go on; UsageError propagates. Stops between views when an interrupt was
//                requested (the views already compared are written first).
//
// The views go through a pipeline of three threads (when more than one view needs work, more
// than one thread is allowed (core/parallel.h ThreadLimit) and a second view in flight, about 64
// bytes per pixel, fits in a quarter of --max-memory):
//   preparer  renders view k+1 (and writes its rendering), decodes its photo and mask;
//   caller    compares view k (the metrics, multi-threaded);
//   writer    writes view k-1's error images and then its record.
// Rendering and the metrics use all threads each, so the overlap mostly fills the time either
// spends in its serial parts (PNG/EXR encoding, decoding, the kernel's copies of written files).
// Error images are handed to the writer in memory (two sets of metrics x width x height floats)
// when those fit in a quarter of --max-memory; else each is streamed to disk while compared, as
// `rephoto compare` does. Values and files are those of the one-view-at-a-time order, byte for
// byte; only the order in which views complete can differ. run.json's timings give the summed
// seconds of each step (render, photos, compare, write) beside the wall time of the view
// stage (views), so the overlap shows.
//
// Thread safety: one thread per fold and workspace; rendering and comparing are multi-threaded
// (the Tally locks).
#pragma once

#include <array>
#include <optional>
#include <vector>

#include "rephoto/compare/compare.h"
#include "rephoto/core/image.h"
#include "rephoto/core/progress.h"
#include "rephoto/eval/fold_model.h"
#include "rephoto/eval/state.h"
#include "rephoto/render/render.h"

namespace rephoto::eval {

// One view between the preparer and the comparison: its rendering, photo and masks.
struct PreparedView {
  render::Rephoto rephoto;  // the renderer's buffers
  Image render;             // the rendering compared (as written or read back; not render_is_8bit)
  // Full-size photos decoded before downscaling: one buffer reused for all of them (a fresh
  // 6-24 MP float image costs more in zeroing and page faults than in decoding).
  Image full_photo;
  Image eval_photo;  // the photo compared (when not photo_is_8bit)
  // 8-bit photos and renderings are compared as their bytes (compare::ComparePhotoAndRender:
  // the same values as their floats v / 255.f, without the conversions), except under --compat.
  Image8 photo8, render8;
  bool photo_is_8bit = false, render_is_8bit = false;
  std::filesystem::path render_path, photo_path;
  std::optional<Mask> mask;
  // The rendering's coverage rule (compare::CompareOptions::min_alpha): the Gaussian alpha
  // threshold for Gaussians rendered by rephoto, else 0 (any alpha > 0, or not black).
  double min_alpha = 0;
  std::string failure;  // why the view could not be prepared (an Error's message)
};

// Buffers reused from view to view (same sizes: no allocation, no page faults) and the models
// kept from fold to fold. Two of each pipeline buffer: one view is compared while the next is
// prepared and the previous one's error images are written.
struct ViewWorkspace {
  ModelCache models;
  compare::CompareWorkspace compare;
  std::array<PreparedView, 2> views;
  std::array<std::vector<Image>, 2> error_images;
  std::vector<uint8_t> rgba;  // the writer's PNG scratch
};

std::vector<size_t> PlanViews(const RunContext& s, const FoldPlan& fold, const FoldModel& model,
                              std::vector<ViewOutcome>& views, Tally& tally, Progress* progress,
                              size_t first = 0, size_t count = 0);

// Fills views[i] for each i in `todo` (PlanViews' result).
void EvaluateViews(const RunContext& s, ViewWorkspace& ws, const FoldPlan& fold,
                   const FoldModel& model, const std::vector<size_t>& todo,
                   render::ViewRenderer* renderer, std::vector<ViewOutcome>& views, Tally& tally,
                   Progress* progress);

}  // namespace rephoto::eval
