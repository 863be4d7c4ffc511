// The first stages of `rephoto evaluate` (eval/state.h): read the scene, open the run folder,
// split the photos.
//
// ReadInputs  reads the scene (scene/read_scene.h), lists views whose photo is missing (left out,
//             warned, recorded in run.json and summary.json) and the output stem of every view
//             (scene/image_name.h OutputStems). Throws Error when no photo exists.
// OpenRun     takes the run folder (run/run_folder.h: one writer), refuses a folder holding a
//             run of another scene (a different set of image names), opens the file hash cache
//             and writes run.json with status "running". A worker (RunContext::worker) takes no
//             lock and writes nothing: the run folder must already hold this scene's run.json.
// MakeSplit   splits the photos on disk by the resolved scheme (UsageError when it is bad) and
//             writes RUN/split (split/split_writer.h); a worker only computes it.
//
// Each fills its part of the RunContext, which is const for the later stages (EvaluateOptions
// and the run path set by the caller). OpenRun takes the lock into `status` and writes run.json
// with the counters and timings of `tally` so far.
//
// Thread safety: each stage mutates the RunContext; call them on one thread.
#pragma once

#include "rephoto/eval/state.h"

namespace rephoto::eval {

void ReadInputs(RunContext& s);
void OpenRun(RunContext& s, const Tally& tally, RunStatus& status);
void MakeSplit(RunContext& s);

}  // namespace rephoto::eval
