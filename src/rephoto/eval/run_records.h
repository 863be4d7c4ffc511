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
// others read outcomes other threads may change: call them on the sequencing thread.
#pragma once

#include <filesystem>
#include <string>

#include <optional>
#include <vector>

#include "rephoto/eval/state.h"

namespace rephoto::eval {

void WriteViewRecord(const RunContext& s, const FoldPlan& fold, const ViewOutcome& outcome);

// Fills `outcome` from `record` (the view record at `path` as run::ReadJsonRecord read it) when
// it holds `key` with status "ok" and the files it points to (rendering; error images when they
// are on) still exist; false otherwise.
bool ReadViewRecord(const RunContext& s, const std::filesystem::path& path,
                    const std::optional<Json>& record, const std::string& key,
                    ViewOutcome* outcome);

// fold.json of `plan` with what `fold` holds so far; status "running", "ok", "incomplete",
// "failed".
void WriteFoldJson(const RunContext& s, const FoldPlan& plan, const FoldOutcome& fold,
                   const std::string& status);

// `result` may be null (a run still going, interrupted or failed).
void WriteRunJson(const RunContext& s, const std::vector<FoldPlan>& plans, const Tally& tally,
                  const RunStatus& run_status, const EvaluateResult* result,
                  const std::string& status);

// `plans` and `outcomes` are the run's folds in index order.
void WriteManifest(const RunContext& s, const std::vector<FoldPlan>& plans,
                   const std::vector<FoldOutcome>& outcomes);

}  // namespace rephoto::eval
