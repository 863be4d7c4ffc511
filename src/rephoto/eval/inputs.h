// The first stages of `rephoto evaluate` (eval/state.h): read the scene, open the run folder,
// split the photos.
//
// ReadInputs  reads the scene (scene/read_scene.h), lists views whose photo is missing (left out,
//             warned, recorded in run.json and summary.json) and the output stem of every view
//             (scene/image_name.h OutputStems). Throws Error when no photo exists.
// OpenRun     takes the run folder (run/run_folder.h: one writer), refuses a folder holding a
//             run of another scene (a different set of image names), opens the file hash cache
//             and writes run.json with status "running". A worker (RunState::worker) takes no
//             lock and writes nothing: the run folder must already hold this scene's run.json.
// MakeSplit   splits the photos on disk by the resolved scheme (UsageError when it is bad) and
//             writes RUN/split (split/split_writer.h); a worker only computes it.
//
// Thread safety: each stage mutates the RunState; call them on one thread.
#pragma once

#include "rephoto/eval/state.h"

namespace rephoto::eval {

void ReadInputs(RunState& s);
void OpenRun(RunState& s);
void MakeSplit(RunState& s);

}  // namespace rephoto::eval
