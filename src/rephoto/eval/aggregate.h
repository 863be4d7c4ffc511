// The aggregate stage of `rephoto evaluate` (eval/state.h): from every fold's view outcomes to
// the run's tables (docs/run-folder.md):
//   per_image.csv  fold, then compare's per_image.csv columns, sorted by fold then name; the
//                  photo column is the scene's image name; failed views have status "failed"
//   per_fold.csv   fold, status, test_images, evaluated_images, completeness, one mean per
//                  metric, message
//   summary.json   schema rephoto.evaluate/1 (summaries with a "count")
// and each fold's fold.json with its final status. Fills `result` (folds, images, metrics).
//
// Thread safety: one thread.
#pragma once

#include <vector>

#include "rephoto/eval/state.h"

namespace rephoto::eval {

// `plans` and `folds` are the run's folds in index order.
void Aggregate(const RunContext& s, const std::vector<FoldPlan>& plans,
               const std::vector<FoldOutcome>& folds, Tally& tally, EvaluateResult* result);

}  // namespace rephoto::eval
