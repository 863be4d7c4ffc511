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

#include "rephoto/eval/fold_model.h"
#include "rephoto/eval/state.h"

namespace rephoto::eval {

// The metric projected, or none (turned off, an external renderer, or it cannot be made: the
// reason is logged once per RunState).
class ProjectionPlan {
 public:
  std::optional<metrics::Metric> Metric(const RunState& s);

 private:
  bool checked_ = false;
  std::optional<metrics::Metric> metric_;
};

void ProjectFold(RunState& s, ModelCache& cache, ProjectionPlan& plan, const FoldState& fold);
void ProjectSharedModel(RunState& s, ModelCache& cache, ProjectionPlan& plan);
void WriteReport(RunState& s);

}  // namespace rephoto::eval
