// The records `rephoto evaluate` keeps in its run folder (docs/run-folder.md has every field):
//   folds/fold_XX/views/<stem>.json  schema rephoto.evaluate.view/1: one view's result and key,
//                                    written last, after its rendering and error images
//   folds/fold_XX/fold.json          schema rephoto.evaluate.fold/1: the fold's command result
//                                    and key, model keys, training/test folders, counts, times
//   run.json                         schema rephoto.evaluate/1: settings, inputs with hashes,
//                                    split, timings, counters, status, outputs
//   manifest.json                    schema rephoto.evaluate.manifest/1: the independent tasks
// Numbers go through run/records.h (NaN = null, infinities "inf"/"-inf"). Every file is written
// atomically.
//
// Thread safety: WriteFoldJson may be called for different folds from different threads; the
// others read RunState fields other threads may change: call them on the sequencing thread.
#pragma once

#include <filesystem>
#include <string>

#include "rephoto/eval/state.h"

namespace rephoto::eval {

void WriteViewRecord(const RunState& s, const FoldState& fold, const ViewOutcome& outcome);

// Fills `outcome` from `record` (the view record at `path` as run::ReadJsonRecord read it) when
// it holds `key` with status "ok" and the files it points to (rendering; error images when they
// are on) still exist; false otherwise.
bool ReadViewRecord(const RunState& s, const std::filesystem::path& path,
                    const std::optional<Json>& record, const std::string& key,
                    ViewOutcome* outcome);

void WriteFoldJson(const RunState& s, const FoldState& fold, const std::string& status);

// `result` may be null (a run still going, interrupted or failed).
void WriteRunJson(const RunState& s, const EvaluateResult* result, const std::string& status);

void WriteManifest(const RunState& s);

}  // namespace rephoto::eval
