// The prepare_fold stage of `rephoto evaluate` (eval/state.h): everything a fold's command and
// rephotos need, from the split and the settings (EvaluateOptions docs in evaluate.h: Sweeps).
//
// PrepareFold fills the fold's training views (all, or the seeded train_count subset), the
// folders the command sees ({images} holds only the training photos, as links; downscaled PNGs
// with train_short_side, cached in CacheDir()/train_photos_s<PX>), the fold's own training and
// test scene folders when they differ from RUN/split, its test views at the evaluation
// resolution (with photo and mask hashes) and its train/test keys. A worker (RunState::worker)
// computes the same state without writing: the submitting run prepared the folders.
// RemoveStaleOutputs removes folds, logs, records, renderings and error images of an earlier
// run with another split, so every file in RUN belongs to this run's settings.
// TrainingScene is the fold's training scene as the command sees it.
//
// Thread safety: PrepareFold mutates the RunState's counters and the fold; one thread.
#pragma once

#include "rephoto/eval/state.h"

namespace rephoto::eval {

void PrepareFold(RunState& s, FoldState& fold);
void RemoveStaleOutputs(const RunState& s);
scene::Scene TrainingScene(const RunState& s, const FoldState& fold);

}  // namespace rephoto::eval
