// `rephoto evaluate --executor slurm`: the run's tasks (EvaluateOptions::only) as Slurm job
// arrays through cluster/slurm.h; docs/cluster.md is the user's guide.
//
// What runs where:
//   the submitting process  PlanEvaluate (evaluate.h; passed in by the caller, which sits above
//                           this executor): reads the scene, splits, prepares the fold folders
//                           and run.json (the run folder on a filesystem every node sees),
//                           writes the settings to RUN/evaluate-settings.json, submits, follows
//   array "fold"            one task per fold: its --reconstruct/--render command (with the
//                           --slurm-reconstruct-* resources) and derived model (--colorize)
//   array "views"           chunks of EvaluateOptions::views_per_task held-out views: render +
//                           compare, one record per view
//   job "aggregate"         per_image.csv, per_fold.csv, summary.json, projection, report
// Each task runs `<program> -q -j <cpus> evaluate --config RUN/evaluate-settings.json --only <task>`
// (cpus: --slurm-cpus-per-task, else all the node's). Tasks whose results are already in the run
// folder with valid keys are not submitted; tasks of an earlier submission still queued or
// running are followed; failed, cancelled or vanished ones are submitted again by the next call.
// The tables are byte-identical to a local run's (the same stage code writes them; only times
// differ).
//
// Thread safety: one call per run folder at a time (the run folder and RUN/slurm are locked).
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "rephoto/eval/options.h"

namespace rephoto::eval {

struct SlurmRunOutcome {
  EvaluateResult result;            // read back from the run folder when it finished
  bool finished = false;            // false with --no-wait, or when the aggregation did not run
  std::vector<std::string> jobs;    // array job ids submitted or followed
  std::vector<std::string> failed;  // one line per failed task, with its log file
  size_t submitted = 0, tasks = 0, tasks_done_before = 0;
  cluster::RunOutcome run;  // what became of each submitted task
};

// How the run is planned: eval::PlanEvaluate (evaluate.h), passed in so that the executor does
// not depend on the sequencer that calls it.
using PlanFunction =
    std::function<EvaluatePlan(const EvaluateOptions& options, size_t views_per_task)>;

SlurmRunOutcome RunEvaluateOnSlurm(const EvaluateOptions& options,
                                   const PlanFunction& plan_evaluate);

// What RunEvaluateOnSlurm submits, for callers that run several evaluations as one set of job
// arrays (sweep): prepares the run (plan_evaluate), writes RUN/evaluate-settings.json and returns
// the three groups "fold", "views", "aggregate" (tasks already done left out; task ids prefixed
// with `prefix`, e.g. "<setting>/").
std::vector<cluster::TaskGroup> PrepareEvaluateTasks(const EvaluateOptions& options,
                                                     const std::string& prefix,
                                                     const PlanFunction& plan_evaluate,
                                                     EvaluatePlan* plan);

// The absolute path of this process's executable (/proc/self/exe).
std::filesystem::path ThisExecutable();

}  // namespace rephoto::eval
