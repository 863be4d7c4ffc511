// What `rephoto evaluate` prints when a run ends, and an EvaluateResult read back from a finished
// run folder (for executors whose aggregation ran in another process).
//
// ResultText: a line of counts, the summary table across folds (run/summary_table.h), failed
// folds, missing photos and a line of times. The files are the results; this is for a terminal.
// ReadEvaluateResult: folds (per_fold.csv), counts, completeness and metric summaries
// (summary.json), missing photos; counters and timings stay zero. Throws Error naming the file
// when the run folder holds no finished aggregation.
//
// Thread safety: pure functions.
#pragma once

#include <filesystem>
#include <string>

#include "rephoto/eval/options.h"

namespace rephoto::eval {

std::string ResultText(const EvaluateResult& result, const std::filesystem::path& out);

EvaluateResult ReadEvaluateResult(const std::filesystem::path& run_dir);

}  // namespace rephoto::eval
