#include "rephoto/eval/projection.h"

#include <functional>

#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/eval/keys.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/project/project.h"
#include "rephoto/report/report.h"
#include "rephoto/splat/scalar_ply.h"

namespace rephoto::eval {
namespace fs = std::filesystem;

namespace {

// A fold's plan and its views' outcomes, as the projection reads them.
struct FoldViews {
  const FoldPlan* plan;
  const std::vector<ViewOutcome>* views;
};

void ProjectOntoGaussians(const RunContext& s, ModelCache& cache, const fs::path& model_path,
                          const std::string& model_key,
                          const std::vector<project::ProjectView>& views,
                          const std::string& metric_name, const fs::path& out) {
  const std::shared_ptr<const splat::GaussianModel> model =
      LoadGaussians(cache, model_path, model_key);
  size_t seen = 0;
  const std::vector<float> mean =
      project::ProjectErrorsOntoGaussians(*model, views, GaussianOptions(s.options), {}, &seen);
  splat::WriteGaussiansWithScalar(model_path, *model, "error", mean, out);
  LogInfo(fmt::format("projected {} of {} views onto {} Gaussians ({} seen) -> {}", metric_name,
                      views.size(), model->size(), seen, out.string()));
}

// Projects one metric's error images of `folds` onto `model_path` (or the cached render model
// when it is that model) into `out`, unless `out` was written with the same key.
void ProjectOnto(const RunContext& s, Tally& tally, ModelCache& cache, const fs::path& model_path,
                 const std::string& model_key, const std::vector<FoldViews>& folds,
                 metrics::Metric metric, const fs::path& out) {
  const std::string metric_name(metrics::MetricName(metric));
  std::vector<project::ProjectView> views;
  Hasher key;
  key.Add(kKeyVersion)
      .Add("project/rendering-depth")
      .Add(model_key)
      .Add(metric_name)
      .Add(RenderSettingsKey(s.options));
  for (const auto& [fold, fold_views] : folds) {
    for (size_t i = 0; i < fold->tests.size() && i < fold_views->size(); ++i) {
      if (!(*fold_views)[i].ok) continue;
      const TestView& test = fold->tests[i];
      project::ProjectView view;
      view.camera = test.camera;
      view.cam_from_world = test.pose;
      view.error_image = fold->dir / "errors" / (test.stem + "." + metric_name + ".exr");
      const fs::path depth = fold->dir / "renders" / (test.stem + ".depth.exr");
      std::error_code exists_ec;
      if (s.options.representation == render::ViewRepresentation::kAuto &&
          fs::is_regular_file(depth, exists_ec)) {
        // The model's own rendering made these errors: its depth map needs no second render.
        view.depth_image = depth;
      }
      view.name = fold->name + "/" + test.stem;
      key.Add(view.name)
          .Add((*fold_views)[i].key)
          .Add(view.depth_image.empty() ? "render" : "file");
      views.push_back(std::move(view));
    }
  }
  if (views.empty()) return;
  const fs::path key_file = fs::path(out).replace_extension(".key");
  std::error_code ec;
  if (fs::is_regular_file(out, ec) && fs::is_regular_file(key_file, ec) &&
      ReadFileToString(key_file) == key.Hex()) {
    return;
  }
  fs::remove(key_file, ec);
  if (IsGaussianModel(s, cache, model_path)) {
    ProjectOntoGaussians(s, cache, model_path, model_key, views, metric_name, out);
  } else {
    project::ProjectOptions options;
    options.backfaces = s.options.backfaces;
    options.higher_is_better = metrics::ErrorImageHigherIsBetter(metric);
    options.model_options.point_radius = s.options.point_radius;
    options.model_options.point_radius_neighbors = s.options.point_neighbors;
    options.model_options.load_textures = false;
    project::ProjectResult projected;
    if (cache.model && cache.model->mesh().vertex_count() > 0 && cache.model_path == model_path) {
      projected = project::ProjectErrors(*cache.model, views, options);
      project::WriteProjectedPly(cache.model->mesh(), projected, out);
    } else {
      const mesh::Mesh mesh = mesh::ReadMesh(model_path);
      projected = project::ProjectErrors(mesh, views, options);
      project::WriteProjectedPly(mesh, projected, out);
    }
    LogInfo(fmt::format("projected {} of {} views onto {} vertices ({} seen) -> {}", metric_name,
                        views.size(), projected.vertex_error.size(), projected.seen_vertices,
                        out.string()));
  }
  WriteTextFileAtomically(key_file, key.Hex());
  tally.Count(&EvaluateCounters::projections);
}

// Runs `project`; a failure is a warning and run.json's projection_error, not the run's.
void GuardProjection(RunStatus& status, const std::function<void()>& project) {
  try {
    project();
  } catch (const Error& e) {
    LogWarning(fmt::format("error projection failed: {}", e.what()));
    status.projection_message = e.what();
  }
}

}  // namespace

std::optional<metrics::Metric> ProjectionPlan::Metric(const RunContext& s) {
  if (checked_) return metric_;
  checked_ = true;
  if (s.options.projection_metric == "none" || s.source == ModelSource::kRender ||
      (s.source == ModelSource::kModel && s.options.model.empty())) {
    return std::nullopt;
  }
  const std::optional<metrics::Metric> metric = metrics::ParseMetric(s.options.projection_metric);
  const bool have_metric = metric && std::find(s.options.metrics.begin(), s.options.metrics.end(),
                                               *metric) != s.options.metrics.end();
  if (!s.options.error_images) {
    LogWarning("no error projection: error images are off (--no-error-images)");
  } else if (!have_metric) {
    LogWarning(fmt::format("no error projection: '{}' is not among the metrics evaluated",
                           s.options.projection_metric));
  } else {
    metric_ = metric;
  }
  return metric_;
}

void ProjectFold(const RunContext& s, ModelCache& cache, ProjectionPlan& plan, const FoldPlan& fold,
                 const FoldOutcome& outcome, size_t fold_count, Tally& tally, RunStatus& status) {
  if (s.source == ModelSource::kModel || !outcome.ok || outcome.model.path.empty()) return;
  const std::optional<metrics::Metric> metric = plan.Metric(s);
  if (!metric) return;
  const auto start = Clock::now();
  const std::string name(metrics::MetricName(*metric));
  const fs::path out =
      s.run / "projected" / (fold_count == 1 ? name + ".ply" : fold.name + "." + name + ".ply");
  GuardProjection(status, [&] {
    ProjectOnto(s, tally, cache,
                HasDefects(s.options.degrade) ? fold.dir / "model.ply" : outcome.model.path,
                outcome.model.model_key, {{&fold, &outcome.views}}, *metric, out);
  });
  tally.AddSeconds(&EvaluateTimings::project, Seconds(start));
}

void ProjectSharedModel(const RunContext& s, ModelCache& cache, ProjectionPlan& plan,
                        const std::vector<FoldPlan>& plans,
                        const std::vector<FoldOutcome>& outcomes, Tally& tally, RunStatus& status) {
  const auto start = Clock::now();
  const std::optional<metrics::Metric> metric =
      s.source == ModelSource::kModel ? plan.Metric(s) : std::nullopt;
  if (metric) {
    const std::string name(metrics::MetricName(*metric));
    GuardProjection(status, [&] {
      std::vector<FoldViews> folds;
      std::vector<const FoldOutcome*> ok_outcomes;
      for (size_t f = 0; f < plans.size(); ++f) {
        if (!outcomes[f].ok) continue;
        folds.push_back({&plans[f], &outcomes[f].views});
        ok_outcomes.push_back(&outcomes[f]);
      }
      fs::path model = fs::absolute(s.options.model).lexically_normal();
      std::string model_key = s.hashes->Hash(model);
      if (HasDefects(s.options.degrade) && !folds.empty()) {
        // Geometry noise and simplification change the geometry the errors belong to; it is
        // the same in every fold (the defects are deterministic).
        model = folds.front().plan->dir / "model.ply";
        model_key = ok_outcomes.front()->model.model_key;
      }
      ProjectOnto(s, tally, cache, model, model_key, folds, *metric,
                  s.run / "projected" / (name + ".ply"));
    });
  }
  tally.AddSeconds(&EvaluateTimings::project, Seconds(start));
}

void WriteReport(const RunContext& s, Tally& tally, RunStatus& status) {
  const auto start = Clock::now();
  if (s.options.report) {
    try {
      report::ReportOptions options;
      options.image_folders = {s.scene.image_root};  // the photos the user named
      report::WriteRunReport(s.run, s.run / "report.html", options);
    } catch (const Error& e) {
      LogWarning(fmt::format("report not written: {}", e.what()));
      status.report_message = e.what();
    }
  }
  tally.AddSeconds(&EvaluateTimings::report, Seconds(start));
}

}  // namespace rephoto::eval
