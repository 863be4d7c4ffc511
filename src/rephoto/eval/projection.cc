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

void ProjectOntoGaussians(RunState& s, ModelCache& cache, const fs::path& model_path,
                          const std::string& model_key,
                          const std::vector<project::ProjectView>& views,
                          const std::string& metric_name, const fs::path& out) {
  const std::shared_ptr<const splat::GaussianModel> model =
      LoadGaussians(cache, model_path, model_key);
  size_t seen = 0;
  const std::vector<float> mean =
      project::ProjectErrorsOntoGaussians(*model, views, GaussianOptions(s.o), {}, &seen);
  splat::WriteGaussiansWithScalar(model_path, *model, "error", mean, out);
  LogInfo(fmt::format("projected {} of {} views onto {} Gaussians ({} seen) -> {}", metric_name,
                      views.size(), model->size(), seen, out.string()));
}

// Projects one metric's error images of `folds` onto `model_path` (or the cached render model
// when it is that model) into `out`, unless `out` was written with the same key.
void ProjectOnto(RunState& s, ModelCache& cache, const fs::path& model_path,
                 const std::string& model_key, const std::vector<const FoldState*>& folds,
                 metrics::Metric metric, const fs::path& out) {
  const std::string metric_name(metrics::MetricName(metric));
  std::vector<project::ProjectView> views;
  Hasher key;
  key.Add(kKeyVersion)
      .Add("project/rendering-depth")
      .Add(model_key)
      .Add(metric_name)
      .Add(RenderSettingsKey(s.o));
  for (const FoldState* fold : folds) {
    for (size_t i = 0; i < fold->tests.size() && i < fold->views.size(); ++i) {
      if (!fold->views[i].ok) continue;
      const TestView& test = fold->tests[i];
      project::ProjectView view;
      view.camera = test.camera;
      view.cam_from_world = test.pose;
      view.error_image = fold->dir / "errors" / (test.stem + "." + metric_name + ".exr");
      const fs::path depth = fold->dir / "renders" / (test.stem + ".depth.exr");
      std::error_code exists_ec;
      if (s.representation == render::ViewRepresentation::kAuto &&
          fs::is_regular_file(depth, exists_ec)) {
        // The model's own rendering made these errors: its depth map needs no second render.
        view.depth_image = depth;
      }
      view.name = fold->name + "/" + test.stem;
      key.Add(view.name).Add(fold->views[i].key).Add(view.depth_image.empty() ? "render" : "file");
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
    options.backfaces = s.o.backfaces;
    options.higher_is_better = metrics::ErrorImageHigherIsBetter(metric);
    options.model_options.point_radius = s.o.point_radius;
    options.model_options.point_radius_neighbors = s.o.point_neighbors;
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
  ++s.counters.projections;
}

// Runs `project`; a failure is a warning and run.json's projection_error, not the run's.
void GuardProjection(RunState& s, const std::function<void()>& project) {
  try {
    project();
  } catch (const Error& e) {
    LogWarning(fmt::format("error projection failed: {}", e.what()));
    s.projection_message = e.what();
  }
}

}  // namespace

std::optional<metrics::Metric> ProjectionPlan::Metric(const RunState& s) {
  if (checked_) return metric_;
  checked_ = true;
  if (s.o.projection_metric == "none" || s.source == ModelSource::kRender ||
      (s.source == ModelSource::kModel && s.o.model.empty())) {
    return std::nullopt;
  }
  const std::optional<metrics::Metric> metric = metrics::ParseMetric(s.o.projection_metric);
  const bool have_metric =
      metric && std::find(s.o.metrics.begin(), s.o.metrics.end(), *metric) != s.o.metrics.end();
  if (!s.o.error_images) {
    LogWarning("no error projection: error images are off (--no-error-images)");
  } else if (!have_metric) {
    LogWarning(fmt::format("no error projection: '{}' is not among the metrics evaluated",
                           s.o.projection_metric));
  } else {
    metric_ = metric;
  }
  return metric_;
}

void ProjectFold(RunState& s, ModelCache& cache, ProjectionPlan& plan, const FoldState& fold) {
  if (s.source == ModelSource::kModel || !fold.ok || fold.model_path.empty()) return;
  const std::optional<metrics::Metric> metric = plan.Metric(s);
  if (!metric) return;
  const auto start = Clock::now();
  const std::string name(metrics::MetricName(*metric));
  const fs::path out =
      s.run / "projected" / (s.folds.size() == 1 ? name + ".ply" : fold.name + "." + name + ".ply");
  GuardProjection(s, [&] {
    ProjectOnto(s, cache, HasDefects(s.o.degrade) ? fold.dir / "model.ply" : fold.model_path,
                fold.model_key, {&fold}, *metric, out);
  });
  s.timings.project += Seconds(start);
}

void ProjectSharedModel(RunState& s, ModelCache& cache, ProjectionPlan& plan) {
  const auto start = Clock::now();
  const std::optional<metrics::Metric> metric =
      s.source == ModelSource::kModel ? plan.Metric(s) : std::nullopt;
  if (metric) {
    const std::string name(metrics::MetricName(*metric));
    GuardProjection(s, [&] {
      std::vector<const FoldState*> folds;
      for (const FoldState& fold : s.folds) {
        if (fold.ok) folds.push_back(&fold);
      }
      fs::path model = fs::absolute(s.o.model).lexically_normal();
      std::string model_key = s.hashes->Hash(model);
      if (HasDefects(s.o.degrade) && !folds.empty()) {
        // Geometry noise and simplification change the geometry the errors belong to; it is
        // the same in every fold (the defects are deterministic).
        model = folds.front()->dir / "model.ply";
        model_key = folds.front()->model_key;
      }
      ProjectOnto(s, cache, model, model_key, folds, *metric,
                  s.run / "projected" / (name + ".ply"));
    });
  }
  s.timings.project += Seconds(start);
}

void WriteReport(RunState& s) {
  const auto start = Clock::now();
  if (s.o.report) {
    try {
      report::ReportOptions options;
      options.image_folders = {s.scene.image_root};  // the photos the user named
      report::WriteRunReport(s.run, s.run / "report.html", options);
    } catch (const Error& e) {
      LogWarning(fmt::format("report not written: {}", e.what()));
      s.report_message = e.what();
    }
  }
  s.timings.report += Seconds(start);
}

}  // namespace rephoto::eval
