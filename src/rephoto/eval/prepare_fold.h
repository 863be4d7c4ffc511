// The prepare_fold stage of `rephoto evaluate` (eval/state.h): everything a fold's command and
// rephotos need, from the split and the settings (EvaluateOptions docs in evaluate.h: Sweeps).
//
// PrepareFold plans fold `index` of the split: its training views (all, or the seeded train_count subset), the
// folders the command sees ({images} holds only the training photos, as links; downscaled PNGs
// with train_short_side, cached in CacheDir()/train_photos_s<PX>), the fold's own training and
// test scene folders when they differ from RUN/split, its test views at the evaluation
// resolution (with photo and mask hashes), its train/test keys and where its derived model goes.
// A worker (RunContext::worker) computes the same plan without writing: the submitting run
// prepared the folders.
// RemoveStaleOutputs removes folds, logs, records, renderings and error images of an earlier
// run with another split, so every file in RUN belongs to this run's settings.
// TrainingScene is the fold's training scene as the command sees it (read back from its
// folder with train_short_side); the fold-model stage computes it once per fold.
//
// Thread safety: PrepareFold counts downscaled photos in the Tally; call the stages on one
// thread.
#pragma once

#include <vector>

#include "rephoto/eval/state.h"

namespace rephoto::eval {

FoldPlan PrepareFold(const RunContext& s, size_t index, Tally& tally);
void RemoveStaleOutputs(const RunContext& s, const std::vector<FoldPlan>& plans);
scene::Scene TrainingScene(const RunContext& s, const FoldPlan& fold);

}  // namespace rephoto::eval
