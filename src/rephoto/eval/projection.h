// The last stages of `rephoto evaluate` (eval/state.h): the error projected onto the model
// (project/project.h; Gaussians: project::ProjectErrorsOntoGaussians into the model's own PLY
// with a `float error` property) and the report (report/report.h).
//
// ProjectFold         per-fold models (--reconstruct, --colorize or defects): the fold's
//                     `projection_metric` error images onto its model, while it is in memory
//                     (RUN/projected/<metric>.ply, or fold_XX.<metric>.ply with several folds)
// ProjectSharedModel  one --model for all folds: the error images of every ok fold onto it
// WriteReport         report.html (report::WriteRunReport), unless turned off
// Each projection is skipped when its file was written with the same key (the model, the
// metric, every view's record key); a failed projection or report is a warning and run.json's
// projection_error / report_error, not a failure of the run.
//
// Thread safety: one thread.
#pragma once

#include <optional>
#include <vector>

#include "rephoto/eval/fold_model.h"
#include "rephoto/eval/state.h"

namespace rephoto::eval {

// The metric projected, or none (turned off, an external renderer, or it cannot be made: the
// reason is logged once per plan).
class ProjectionPlan {
 public:
  std::optional<metrics::Metric> Metric(const RunContext& s);

 private:
  bool checked_ = false;
  std::optional<metrics::Metric> metric_;
};

// `fold_count`: the run's folds (one fold writes <metric>.ply). A failure goes to
// status.projection_message.
void ProjectFold(const RunContext& s, ModelCache& cache, ProjectionPlan& plan,
                 const FoldPlan& fold, const FoldOutcome& outcome, size_t fold_count,
                 Tally& tally, RunStatus& status);
// `plans` and `outcomes` are the run's folds in index order.
void ProjectSharedModel(const RunContext& s, ModelCache& cache, ProjectionPlan& plan,
                        const std::vector<FoldPlan>& plans,
                        const std::vector<FoldOutcome>& outcomes, Tally& tally,
                        RunStatus& status);
// A failure goes to status.report_message.
void WriteReport(const RunContext& s, Tally& tally, RunStatus& status);

}  // namespace rephoto::eval
