// The rephoto_views stage of `rephoto evaluate` (eval/state.h): render a fold's held-out views
// with rephoto's renderer (or take the external renderer's images), compare them with the
// photos at the evaluation resolution and write one record per view.
//
// PlanViews      for views [first, first + count) of the fold (in fold.tests order; count 0 =
//                to the end): each view's record key and render key (keys.h); a view whose
//                record (folds/fold_XX/views/<stem>.json) holds the same key with status "ok"
//                and whose outputs exist is reused; a view whose rendering has the same render
//                key is only compared again. Returns the indices of the views that need work.
// EvaluateViews  renders (renderer, when not reused) and compares each view: the photo
//                (downscaled once into CacheDir()/eval_photos/<stem>.png with eval_short_side),
//                its mask, the rendering's coverage (Gaussians: alpha >= min_alpha) through
//                compare::ComparePhotoAndRender; writes renders/<stem>.png + .depth.exr,
//                errors/<stem>.<metric>.exr|png and the view record last. A view that fails is
//                recorded in its outcome (message) and the others go on; UsageError propagates.
//                Stops between views when an interrupt was requested.
//
// Thread safety: one thread per fold and workspace; rendering and comparing are multi-threaded.
#pragma once

#include <vector>

#include "rephoto/compare/compare.h"
#include "rephoto/core/image.h"
#include "rephoto/core/progress.h"
#include "rephoto/eval/fold_model.h"
#include "rephoto/eval/state.h"
#include "rephoto/render/render.h"

namespace rephoto::eval {

// Buffers reused from view to view (same sizes: no allocation, no page faults) and the models
// kept from fold to fold.
struct ViewWorkspace {
  ModelCache models;
  compare::CompareWorkspace compare;
  // Full-size photos decoded before downscaling: one buffer reused for all of them (a fresh
  // 6-24 MP float image costs more in zeroing and page faults than in decoding).
  Image full_photo;
  render::Rephoto rephoto;
  Image render, eval_photo;
};

std::vector<size_t> PlanViews(RunState& s, FoldState& fold, Progress* progress, size_t first = 0,
                              size_t count = 0);

void EvaluateViews(RunState& s, ViewWorkspace& ws, FoldState& fold,
                   const std::vector<size_t>& todo, render::ViewRenderer* renderer,
                   Progress* progress);

}  // namespace rephoto::eval
