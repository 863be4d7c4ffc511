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

#include "rephoto/eval/state.h"

namespace rephoto::eval {

void Aggregate(RunState& s, EvaluateResult* result);

}  // namespace rephoto::eval
