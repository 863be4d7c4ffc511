// The run_command stage of `rephoto evaluate` (eval/state.h): a fold's --reconstruct or --render
// command (evaluate.h documents the templates, placeholders and failure cases).
//
// RunFoldCommand substitutes the fold's placeholders, reuses the recorded result when fold.json
// holds the same command key with status "ok" and the outputs are still valid, and otherwise
// runs the command (core/process.h, with --command-timeout) into an emptied {out}, logging to
// RUN/logs/fold_XX.<kind>.log, then validates what it wrote. Failures fail the fold (recorded,
// not thrown). With `may_run` false (a task that needs the fold's finished command) nothing is
// run: a fold whose command result cannot be reused fails with "not reconstructed yet".
// Returns what became of the command (CommandOutcome::ok false with the message when it failed;
// `interrupted` when the run was interrupted while it ran); the fold's plan is not changed.
// Writes fold.json ("running") before it starts a command. Throws Error when the command cannot
// be started at all.
//
// Thread safety: different folds may run at once in worker threads; each writes only its fold's
// files and adds to the Tally (which locks).
#pragma once

#include "rephoto/eval/state.h"

namespace rephoto::eval {

CommandOutcome RunFoldCommand(const RunContext& s, const FoldPlan& fold, bool may_run,
                              Tally& tally);

}  // namespace rephoto::eval
