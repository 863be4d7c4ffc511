#include "rephoto/eval/options.h"

#include <algorithm>
#include <charconv>

#include "rephoto/compare/compare.h"
#include "rephoto/compare/compat_compare.h"
#include "rephoto/eval/command_template.h"
#include "rephoto/split/split.h"

namespace rephoto::eval {

std::optional<Executor> ParseExecutor(std::string_view name) {
  if (name == "local") return Executor::kLocal;
  if (name == "slurm") return Executor::kSlurm;
  return std::nullopt;
}

std::string_view ExecutorName(Executor executor) {
  return executor == Executor::kSlurm ? "slurm" : "local";
}

std::string_view GaussianModeName(splat::GaussianMode mode) {
  return mode == splat::GaussianMode::kAntialiased ? "antialiased" : "classic";
}

namespace {

size_t ParseIndex(std::string_view text, std::string_view task) {
  size_t value = 0;
  const auto [ptr, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || ptr != text.data() + text.size() || text.empty()) {
    throw UsageError(fmt::format(
        "--only '{}': expected fold:F, views:F:FIRST:COUNT or aggregate (F, FIRST, COUNT "
        "numbers)",
        task));
  }
  return value;
}

}  // namespace

TaskSpec ParseTaskSpec(std::string_view text) {
  std::vector<std::string_view> parts;
  for (size_t begin = 0;;) {
    const size_t colon = text.find(':', begin);
    parts.push_back(text.substr(begin, colon - begin));
    if (colon == std::string_view::npos) break;
    begin = colon + 1;
  }
  TaskSpec task;
  if (parts.size() == 1 && parts[0] == "aggregate") return task;
  if (parts.size() == 2 && parts[0] == "fold") {
    task.kind = EvaluateTask::Kind::kFold;
    task.fold = ParseIndex(parts[1], text);
    return task;
  }
  if (parts.size() == 4 && parts[0] == "views") {
    task.kind = EvaluateTask::Kind::kViews;
    task.fold = ParseIndex(parts[1], text);
    task.first = ParseIndex(parts[2], text);
    task.count = ParseIndex(parts[3], text);
    if (task.count > 0) return task;
  }
  ParseIndex("", text);  // throws the usage message
  return task;
}

// The one place a run's compat metric list is decided: the compare stage (CompatCompareSettings),
// the view records, the tables and the reference files all take it from here, so a preset that
// gains a metric (LPIPS with --lpips-weights) flows through every output.
std::vector<metrics::Metric> CompatMetrics(const EvaluateOptions& options) {
  if (!options.compat) return {};
  // The one rule of compare/compat_compare.h: the requested list, else psnr, ssim and lpips
  // when LPIPS weights are given (--lpips-weights or $REPHOTO_LPIPS_WEIGHTS).
  return compare::ResolveCompatMetrics(*options.compat, options.compat_metrics,
                                       options.lpips_weights);
}

const std::vector<std::string>& CommandPlaceholders() {
  static const std::vector<std::string> names = {
      "train",       "sparse",          "transforms", "images", "train_list", "test",
      "test_sparse", "test_transforms", "test_list",  "out",    "fold",       "threads"};
  return names;
}

std::string ResolvedScheme(const EvaluateOptions& options, size_t photo_count) {
  if (!options.scheme.empty()) return options.scheme;
  // 3DGS's llffhold 8 and nerfstudio's eval_interval 8: the test sets of published tables.
  if (options.compat) return "every:8";
  if (options.source() == ModelSource::kModel && !options.colorize && !options.texture) {
    return "none";
  }
  return photo_count >= 5 ? "kfold:5" : "loo";
}

bool HasDefects(const degrade::DegradeOptions& d) {
  return d.texture_noise > 0 || d.geometry_noise > 0 || d.simplify > 0;
}

ModelSource EvaluateOptions::source() const {
  if (!render.empty()) return ModelSource::kRender;
  if (!reconstruct.empty()) return ModelSource::kReconstruct;
  return ModelSource::kModel;
}

void EvaluateOptions::Check() const {
  if (scene.empty()) throw UsageError("evaluate: no scene given (--scene)");
  if (out.empty()) throw UsageError("evaluate: no run directory given (--out)");
  if (!scheme.empty()) split::ParseScheme(scheme);  // syntax now, before anything is written
  const int sources = (!render.empty()) + (!reconstruct.empty());
  if (sources > 1) throw UsageError("evaluate: give either --reconstruct or --render, not both");
  if (!reconstruct.empty() && model.empty()) {
    throw UsageError("evaluate: --reconstruct needs --model, the model's path inside {out}");
  }
  if (!reconstruct.empty() && model.is_absolute()) {
    throw UsageError(fmt::format(
        "evaluate: with --reconstruct, --model is the model's path inside {{out}} (got the "
        "absolute path {})",
        model.string()));
  }
  if (render.empty() && reconstruct.empty() && model.empty() &&
      representation != render::ViewRepresentation::kIbr) {
    throw UsageError(
        "evaluate: give a model source: --model FILE, --reconstruct CMD --model "
        "PATH, or --render CMD");
  }
  if (!render.empty() && !model.empty()) {
    throw UsageError("evaluate: --render renders by itself; --model is not used with it");
  }
  if (colorize && texture) {
    throw UsageError("evaluate: give either --colorize (vertex colours) or --texture, not both");
  }
  if (!render.empty() && (colorize || texture)) {
    throw UsageError(fmt::format("evaluate: --{} needs a model (not --render)",
                                 colorize ? "colorize" : "texture"));
  }
  if (!render.empty() && HasDefects(degrade)) {
    throw UsageError(
        "evaluate: model defects (--texture-noise, --geometry-noise, --simplify) need a model "
        "rendered by rephoto (not --render)");
  }
  if (!(degrade.texture_noise >= 0) || !(degrade.geometry_noise >= 0) ||
      !(degrade.simplify >= 0 && degrade.simplify < 1)) {
    throw UsageError(fmt::format(
        "evaluate: defects out of range (texture noise {} >= 0, geometry noise {} >= 0, "
        "simplify {} in [0, 1))",
        degrade.texture_noise, degrade.geometry_noise, degrade.simplify));
  }
  if (!reconstruct.empty())
    TemplatePlaceholders(reconstruct, CommandPlaceholders(), "--reconstruct");
  if (!render.empty()) TemplatePlaceholders(render, CommandPlaceholders(), "--render");
  if (representation != render::ViewRepresentation::kAuto && !render.empty()) {
    throw UsageError("evaluate: --representation is for rephoto's renderers, not --render");
  }
  if (!depth_maps.empty() && representation != render::ViewRepresentation::kIbr) {
    throw UsageError("evaluate: --depth-maps is for --representation ibr");
  }
  if (jobs < 1) throw UsageError("evaluate: --jobs must be at least 1");
  if (samples_per_pixel < 1) throw UsageError("evaluate: --spp must be at least 1");
  if (train_count < 0 || train_short_side < 0 || eval_short_side < 0) {
    throw UsageError("evaluate: counts and sizes must not be negative");
  }
  if (metrics.empty()) throw UsageError("evaluate: no metric selected");
  if (!compat && !compat_metrics.empty()) {
    throw UsageError("evaluate: --compat-metrics needs a --compat preset (3dgs, nerfstudio)");
  }
  if (compat) {
    compare::CheckCompatMetrics(*compat, CompatMetrics(*this));
    if (resize) {
      throw UsageError(
          "evaluate: --compat compares each rendering at its photo's size, as the reference "
          "scripts do; --resize does not apply");
    }
  }
  if (error_image_metrics && *error_image_metrics != metrics::AllMetrics()) {
    for (metrics::Metric m : *error_image_metrics) {
      if (std::find(metrics.begin(), metrics.end(), m) == metrics.end()) {
        throw UsageError(fmt::format("evaluate: --error-image-metrics: {} is not among --metrics",
                                     metrics::MetricName(m)));
      }
    }
  }
  if (projection_metric != "none" && !metrics::ParseMetric(projection_metric)) {
    throw UsageError(fmt::format("evaluate: unknown projection metric '{}'", projection_metric));
  }
  if (!only.empty()) ParseTaskSpec(only);  // UsageError when malformed
  if (executor == Executor::kSlurm && !only.empty()) {
    throw UsageError("evaluate: --only runs one task here; it does not go with --executor slurm");
  }
  compare::CompareOptions c;
  c.photos = c.renders = c.out = "-";
  c.metrics = metrics;
  c.metric_options = metric_options;
  c.exposure = exposure;
  c.lpips_weights = lpips_weights;
  c.lpips_net = lpips_net;
  try {
    c.Check();
  } catch (const Error& e) {
    throw UsageError(e.what());
  }
}

std::vector<metrics::Metric> ErrorImageMetrics(const EvaluateOptions& options) {
  if (options.error_image_metrics == metrics::AllMetrics()) return {};  // all
  std::vector<metrics::Metric> wanted =
      options.error_image_metrics.value_or(std::vector<metrics::Metric>{});
  if (!options.error_image_metrics && !options.metrics.empty()) {
    wanted.push_back(metrics::HeadlineMetric(options.metrics));
  }
  const std::optional<metrics::Metric> projected = metrics::ParseMetric(options.projection_metric);
  if (projected) wanted.push_back(*projected);
  std::vector<metrics::Metric> list;  // in options.metrics order, each once
  for (metrics::Metric m : options.metrics) {
    if (std::find(wanted.begin(), wanted.end(), m) != wanted.end()) list.push_back(m);
  }
  // Every metric's: the same as "all" (and the same keys as runs made before the option).
  if (list.size() == options.metrics.size()) return {};
  return list;
}

std::vector<metrics::Metric> WrittenErrorImageMetrics(const EvaluateOptions& options) {
  if (!options.error_images) return {};
  std::vector<metrics::Metric> list = ErrorImageMetrics(options);
  return list.empty() ? options.metrics : list;
}

bool WritesDepthImages(const EvaluateOptions& options, bool gaussians) {
  return options.depth_images ||
         (options.representation == render::ViewRepresentation::kAuto && !gaussians &&
          options.render.empty() && options.projection_metric != "none");
}

}  // namespace rephoto::eval
