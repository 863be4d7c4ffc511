// Sequences the stages of `rephoto evaluate` (eval/state.h lists them) for a whole run, or for
// one task of a run (EvaluateOptions::only) as an executor on another machine runs it.
#include "rephoto/eval/evaluate.h"

#include <atomic>
#include <charconv>
#include <condition_variable>
#include <mutex>
#include <thread>

#include "rephoto/core/file.h"
#include "rephoto/core/process.h"
#include "rephoto/core/progress.h"
#include "rephoto/eval/aggregate.h"
#include "rephoto/eval/command.h"
#include "rephoto/eval/fold_model.h"
#include "rephoto/eval/inputs.h"
#include "rephoto/eval/prepare_fold.h"
#include "rephoto/eval/projection.h"
#include "rephoto/eval/records.h"
#include "rephoto/eval/rephoto_views.h"
#include "rephoto/eval/run_command.h"
#include "rephoto/eval/settings.h"
#include "rephoto/eval/slurm_executor.h"
#include "rephoto/eval/state.h"
#include "rephoto/split/split_writer.h"

namespace rephoto::eval {
namespace fs = std::filesystem;

namespace {

// The rephoto stage of one fold: its model, which views need work, the renderer when one does,
// then render and compare them.
void RephotoFold(RunState& s, ViewWorkspace& ws, FoldState& fold, Progress* progress,
                 size_t first = 0, size_t count = 0) {
  const auto start = Clock::now();
  std::optional<mesh::Mesh> mesh;  // read by ResolveFoldModel unless its key was known
  ResolveFoldModel(s, ws.models, fold, &mesh);
  const std::vector<size_t> todo = PlanViews(s, fold, progress, first, count);
  bool need_renderer = false;
  for (size_t i : todo) {
    need_renderer |= s.source != ModelSource::kRender && !fold.views[i].reuse_render;
  }
  std::unique_ptr<render::ViewRenderer> renderer;
  if (need_renderer) renderer = MakeFoldRenderer(s, ws.models, fold, &mesh);
  if (!s.worker) WriteFoldJson(s, fold, "running");
  EvaluateViews(s, ws, fold, todo, renderer.get(), progress);
  fold.seconds = Seconds(start);
}

// The common start of every invocation: settings, inputs, run folder, split, folds.
void Start(RunState& s) {
  s.start = Clock::now();
  s.start_cpu = ProcessCpuSeconds();
  s.o.Check();
  s.source = s.o.source();
  s.representation =
      render::ParseRepresentation(s.o.representation).value_or(render::ViewRepresentation::kAuto);
  s.run = fs::absolute(s.o.out).lexically_normal();
  s.worker = !s.o.only.empty();
  if (s.source == ModelSource::kModel && !s.o.model.empty()) {
    std::error_code ec;
    REPHOTO_CHECK(fs::is_regular_file(s.o.model, ec), "{}: no such model file (--model)",
                  s.o.model.string());
  }
  auto phase = Clock::now();
  ReadInputs(s);
  OpenRun(s);
  MakeSplit(s);
  if (!s.worker) WriteRunJson(s, nullptr, "running");
  s.timings.split += Seconds(phase);
  s.folds.resize(s.split.folds.size());
  for (size_t f = 0; f < s.folds.size(); ++f) {
    s.folds[f].index = f;
    s.folds[f].name = split::FoldFolderName(f, s.folds.size());
  }
}

void PrepareFolds(RunState& s) {
  const auto phase = Clock::now();
  for (FoldState& fold : s.folds) PrepareFold(s, fold);
  if (!s.worker) RemoveStaleOutputs(s);
  s.timings.prepare += Seconds(phase);
}

// Aggregation, manifest, run.json, the shared model's projection and the report.
EvaluateResult Finish(RunState& s, ViewWorkspace& ws, ProjectionPlan& plan) {
  EvaluateResult result;
  result.missing_photos = s.missing_photos;
  Aggregate(s, &result);
  WriteManifest(s);
  bool incomplete = !s.missing_photos.empty();
  for (const FoldResult& fr : result.folds) incomplete |= !fr.ok;
  result.exit_code = incomplete ? ExitCode::kIncomplete : ExitCode::kOk;
  const std::string status = incomplete ? "incomplete" : "ok";
  WriteRunJson(s, &result, status);  // the report reads it
  ProjectSharedModel(s, ws.models, plan);
  WriteReport(s);
  s.timings.total = Seconds(s.start);
  s.timings.rephoto_cpu = ProcessCpuSeconds() - s.start_cpu;
  result.counters = s.counters;
  result.timings = s.timings;
  WriteRunJson(s, &result, status);
  result.timings.total = Seconds(s.start);
  return result;
}

// Runs the folds' commands in background threads, `jobs` at a time, in fold order; the calling
// thread waits for each fold's command in turn (WaitFor) and does the rephoto stage meanwhile.
class CommandPool {
 public:
  explicit CommandPool(RunState& s)
      : s_(s), done_(s.folds.size(), s.source == ModelSource::kModel ? 1 : 0) {
    if (s.source == ModelSource::kModel) return;
    const int count = std::min<int>(s.o.jobs, static_cast<int>(s.folds.size()));
    for (int w = 0; w < count; ++w) workers_.emplace_back([this] { Work(); });
  }
  // On an exception: no new commands; wait for the running ones.
  ~CommandPool() { Join(); }
  void WaitFor(size_t fold) {
    std::unique_lock<std::mutex> lock(mutex_);
    done_cv_.wait(lock, [&] { return done_[fold] != 0; });
  }
  void Join() {
    stop_ = true;
    for (std::thread& t : workers_) {
      if (t.joinable()) t.join();
    }
    workers_.clear();
  }

 private:
  void Work() {
    for (;;) {
      const size_t f = next_.fetch_add(1);
      if (f >= s_.folds.size()) return;
      FoldState& fold = s_.folds[f];
      if (InterruptRequested() || stop_) {
        fold.interrupted = true;
      } else {
        try {
          RunFoldCommand(s_, fold);
        } catch (const Error& e) {
          FailFold(fold, fmt::format("{}: {}", fold.name, e.what()));
        }
      }
      {
        std::lock_guard<std::mutex> lock(mutex_);
        done_[f] = 1;
      }
      done_cv_.notify_all();
    }
  }

  RunState& s_;
  std::mutex mutex_;
  std::condition_variable done_cv_;
  std::vector<char> done_;
  std::vector<std::thread> workers_;
  std::atomic<size_t> next_{0};
  std::atomic<bool> stop_{false};
};

// The rephoto stage of every fold, overlapping the commands of the next folds.
void RephotoAllFolds(RunState& s, ViewWorkspace& ws, ProjectionPlan& plan, CommandPool& pool) {
  size_t total_views = 0;
  for (const FoldState& fold : s.folds) total_views += fold.tests.size();
  Progress progress("evaluate", total_views);
  for (FoldState& fold : s.folds) {
    pool.WaitFor(fold.index);
    if (InterruptRequested() || fold.interrupted) break;
    if (fold.command_reused) ++s.counters.folds_reused;
    if (fold.ok) {
      try {
        RephotoFold(s, ws, fold, &progress);
      } catch (const UsageError&) {
        throw;
      } catch (const Error& e) {
        const std::string what = e.what();
        FailFold(fold, what.rfind(fold.name + ":", 0) == 0 ? what : fold.name + ": " + what);
      }
    }
    if (!fold.ok) {
      LogWarning(fold.message);
      for (const TestView& test : fold.tests) {
        progress.Advance(fmt::format("{} {} (fold failed)", fold.name, test.stem));
      }
    }
    WriteFoldJson(s, fold, fold.ok ? "ok" : "failed");
    if (!InterruptRequested())
      ProjectFold(s, ws.models, plan, fold);  // while its model is in memory
  }
}

EvaluateResult RunAll(RunState& s) {
  Start(s);
  PrepareFolds(s);
  size_t total_views = 0;
  for (const FoldState& fold : s.folds) total_views += fold.tests.size();
  LogInfo(fmt::format("evaluate: {} photos ({} missing), {} folds ({}), {} test views -> {}",
                      s.photo_names.size(), s.missing_photos.size(), s.folds.size(),
                      s.split.scheme.ToString(), total_views, s.run.string()));
  ViewWorkspace ws;
  ProjectionPlan plan;
  {
    CommandPool pool(s);
    RephotoAllFolds(s, ws, plan, pool);
    pool.Join();
  }
  s.hashes->Save();
  if (InterruptRequested()) {
    WriteRunJson(s, nullptr, "interrupted");
    throw Interrupted(fmt::format(
        "{}: interrupted; finished folds and views are kept: rerun the same command to resume",
        s.run.string()));
  }
  return Finish(s, ws, plan);
}

// ------------------------------------------------------------------------------ tasks

struct Task {
  enum class Kind { kFold, kViews, kAggregate } kind = Kind::kAggregate;
  size_t fold = 0, first = 0, count = 0;
};

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

Task ParseTask(std::string_view text) {
  std::vector<std::string_view> parts;
  for (size_t begin = 0;;) {
    const size_t colon = text.find(':', begin);
    parts.push_back(text.substr(begin, colon - begin));
    if (colon == std::string_view::npos) break;
    begin = colon + 1;
  }
  Task task;
  if (parts.size() == 1 && parts[0] == "aggregate") return task;
  if (parts.size() == 2 && parts[0] == "fold") {
    task.kind = Task::Kind::kFold;
    task.fold = ParseIndex(parts[1], text);
    return task;
  }
  if (parts.size() == 4 && parts[0] == "views") {
    task.kind = Task::Kind::kViews;
    task.fold = ParseIndex(parts[1], text);
    task.first = ParseIndex(parts[2], text);
    task.count = ParseIndex(parts[3], text);
    if (task.count > 0) return task;
  }
  ParseIndex("", text);  // throws the usage message
  return task;
}

// A fold's finished command (never run here): reused, or the fold fails with the recorded reason.
void ReuseFoldCommand(RunState& s, FoldState& fold) {
  if (s.source == ModelSource::kModel) return;
  RunFoldCommand(s, fold, /*may_run=*/false);
  if (!fold.ok && fold.previous && !fold.previous->value("message", "").empty()) {
    fold.message = fold.previous->value("message", "");
  }
}

// fold:F: the fold's command and its derived model (colours, defects).
ExitCode RunFoldTask(RunState& s, FoldState& fold) {
  PrepareFold(s, fold);
  if (s.source != ModelSource::kModel) {
    RunFoldCommand(s, fold);
    if (fold.interrupted) {
      throw Interrupted(fmt::format("{} {}: interrupted", s.run.string(), fold.name));
    }
  }
  if (fold.ok && s.source != ModelSource::kRender) {
    ViewWorkspace ws;
    std::optional<mesh::Mesh> mesh;
    try {
      ResolveFoldModel(s, ws.models, fold, &mesh);
      if (s.DerivesModel() && !fold.gaussians) LoadFoldModel(s, ws.models, fold, &mesh);
    } catch (const UsageError&) {
      throw;
    } catch (const Error& e) {
      FailFold(fold, fmt::format("{}: {}", fold.name, e.what()));
    }
  }
  WriteFoldJson(s, fold, fold.ok ? "ok" : "failed");
  if (!fold.ok) LogWarning(fold.message);
  return fold.ok ? ExitCode::kOk : ExitCode::kIncomplete;
}

// views:F:FIRST:COUNT: render and compare those views of a fold whose command is finished.
ExitCode RunViewsTask(RunState& s, FoldState& fold, size_t first, size_t count) {
  PrepareFold(s, fold);
  ReuseFoldCommand(s, fold);
  if (!fold.ok) {
    LogWarning(fold.message);
    return ExitCode::kIncomplete;
  }
  ViewWorkspace ws;
  const size_t end = std::min(fold.tests.size(), first + count);
  Progress progress("evaluate", end > first ? end - first : 0);
  try {
    RephotoFold(s, ws, fold, &progress, first, count);
  } catch (const UsageError&) {
    throw;
  } catch (const Error& e) {
    if (InterruptRequested()) throw;
    LogWarning(fmt::format("{}: {}", fold.name, e.what()));
    return ExitCode::kIncomplete;
  }
  s.hashes->Save();
  if (InterruptRequested()) throw Interrupted(fmt::format("{}: interrupted", s.run.string()));
  for (size_t i = first; i < end; ++i) {
    if (!fold.views[i].ok) return ExitCode::kIncomplete;
  }
  return ExitCode::kOk;
}

// aggregate: everything after the views, from the records the other tasks wrote.
EvaluateResult RunAggregateTask(RunState& s) {
  PrepareFolds(s);
  ViewWorkspace ws;
  ProjectionPlan plan;
  for (FoldState& fold : s.folds) {
    ReuseFoldCommand(s, fold);
    if (!fold.ok) continue;
    try {
      std::optional<mesh::Mesh> mesh;
      ResolveFoldModel(s, ws.models, fold, &mesh);
      PlanViews(s, fold, nullptr);
      for (ViewOutcome& view : fold.views) {
        if (!view.reused) view.message = fmt::format("{} {}: not evaluated", fold.name, view.stem);
      }
      if (s.source != ModelSource::kModel && !fold.gaussians && s.DerivesModel()) {
        LoadFoldModel(s, ws.models, fold, &mesh);  // the model the errors are projected onto
      }
      ProjectFold(s, ws.models, plan, fold);
    } catch (const UsageError&) {
      throw;
    } catch (const Error& e) {
      FailFold(fold, fmt::format("{}: {}", fold.name, e.what()));
    }
  }
  s.hashes->Save();
  return Finish(s, ws, plan);
}

EvaluateResult RunTask(RunState& s) {
  const Task task = ParseTask(s.o.only);
  Start(s);
  EvaluateResult result;
  if (task.kind == Task::Kind::kAggregate) {
    // The task did its work when the tables are written; whether the run is complete is in
    // summary.json (the submitting process reads it back).
    result = RunAggregateTask(s);
    result.exit_code = ExitCode::kOk;
    return result;
  }
  REPHOTO_CHECK_USAGE(task.fold < s.folds.size(), "--only {}: the run has {} folds", s.o.only,
                      s.folds.size());
  FoldState& fold = s.folds[task.fold];
  result.exit_code = task.kind == Task::Kind::kFold ? RunFoldTask(s, fold)
                                                    : RunViewsTask(s, fold, task.first, task.count);
  return result;
}

// Whether a fold's task (command, derived model) has its results, and the fold's base key.
bool FoldReady(RunState& s, ViewWorkspace& ws, FoldState& fold) {
  if (s.source != ModelSource::kModel) {
    RunFoldCommand(s, fold, /*may_run=*/false);
    if (!fold.ok) return false;
  }
  try {
    std::optional<mesh::Mesh> mesh;
    ResolveFoldModel(s, ws.models, fold, &mesh);
  } catch (const Error&) {
    return false;  // the fold task reports it
  }
  if (!s.DerivesModel() || fold.gaussians) return true;
  std::error_code ec;
  return fs::is_regular_file(DerivedModelPath(s, fold), ec) &&
         fs::is_regular_file(fold.dir / "model.key", ec) &&
         ReadFileToString(fold.dir / "model.key") == fold.colorize_key;
}

}  // namespace

EvaluatePlan PlanEvaluate(const EvaluateOptions& options, size_t views_per_task) {
  REPHOTO_CHECK_USAGE(views_per_task > 0, "evaluate: views per task must be at least 1");
  EvaluateOptions o = options;
  o.only.clear();
  o.executor = "local";
  RunState s(o);
  const fs::path run_json = fs::absolute(o.out).lexically_normal() / "run.json";
  const std::optional<Json> previous = run::ReadJsonRecord(run_json);
  const std::string previous_status = previous ? previous->value("status", "") : "";
  Start(s);
  PrepareFolds(s);
  Hasher settings;
  settings.Add(SettingsJson(o).dump());
  if (s.source == ModelSource::kModel && !o.model.empty()) settings.Add(s.hashes->Hash(o.model));
  const std::string settings_key = settings.Hex();
  EvaluatePlan plan;
  plan.run = s.run;
  plan.folds = s.folds.size();
  ViewWorkspace ws;
  bool all_done = true;
  Hasher aggregate_key;
  aggregate_key.Add(settings_key);
  std::vector<EvaluateTask> view_tasks;
  for (FoldState& fold : s.folds) {
    plan.views += fold.tests.size();
    const bool fold_task = s.source != ModelSource::kModel || s.DerivesModel();
    const bool ready = FoldReady(s, ws, fold);
    const std::string fold_key =
        Hasher().Add(settings_key).Add(fold.train_key).Add(fold.test_key).Hex();
    if (fold_task) {
      plan.tasks.push_back({EvaluateTask::Kind::kFold, fmt::format("fold:{}", fold.index),
                            fold.index, 0, fold_key, ready});
      all_done &= ready;
    }
    for (size_t first = 0; first < fold.tests.size(); first += views_per_task) {
      const size_t count = std::min(views_per_task, fold.tests.size() - first);
      EvaluateTask task{EvaluateTask::Kind::kViews,
                        fmt::format("views:{}:{}:{}", fold.index, first, count), fold.index, count};
      Hasher key;
      key.Add(fold_key);
      task.done = ready && PlanViews(s, fold, nullptr, first, count).empty();
      for (size_t i = first; i < first + count; ++i) {
        key.Add(fold.tests[i].stem).Add(ready ? fold.views[i].key : std::string());
      }
      task.key = key.Hex();
      aggregate_key.Add(task.key);
      all_done &= task.done;
      view_tasks.push_back(std::move(task));
    }
  }
  plan.tasks.insert(plan.tasks.end(), view_tasks.begin(), view_tasks.end());
  std::error_code ec;
  const bool aggregated = (previous_status == "ok" || previous_status == "incomplete") &&
                          fs::is_regular_file(s.run / "summary.json", ec);
  plan.tasks.push_back({EvaluateTask::Kind::kAggregate, "aggregate", 0, 0, aggregate_key.Hex(),
                        all_done && aggregated});
  if (plan.tasks.back().done && previous) {
    run::WriteJsonRecord(run_json, *previous);  // nothing to do: the finished run's record stays
  }
  s.hashes->Save();
  return plan;
}

// ------------------------------------------------------------------------------ public API

const std::vector<std::string>& CommandPlaceholders() {
  static const std::vector<std::string> names = {
      "train",       "sparse",          "transforms", "images", "train_list", "test",
      "test_sparse", "test_transforms", "test_list",  "out",    "fold",       "threads"};
  return names;
}

std::string ResolvedScheme(const EvaluateOptions& options, size_t photo_count) {
  if (!options.scheme.empty()) return options.scheme;
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
  const std::optional<render::ViewRepresentation> parsed_representation =
      render::ParseRepresentation(representation);
  if (render.empty() && reconstruct.empty() && model.empty() &&
      parsed_representation != render::ViewRepresentation::kIbr) {
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
  if (!parsed_representation) {
    throw UsageError(fmt::format(
        "evaluate: --representation '{}' is not one of auto (the model as it is), vdt "
        "(view-dependent texturing on the model), ibr (image-based rendering with depth maps), "
        "gaussians (the model as 3D Gaussian splats)",
        representation));
  }
  if (parsed_representation != render::ViewRepresentation::kAuto && !render.empty()) {
    throw UsageError("evaluate: --representation is for rephoto's renderers, not --render");
  }
  if (!depth_maps.empty() && parsed_representation != render::ViewRepresentation::kIbr) {
    throw UsageError("evaluate: --depth-maps is for --representation ibr");
  }
  if (jobs < 1) throw UsageError("evaluate: --jobs must be at least 1");
  if (samples_per_pixel < 1) throw UsageError("evaluate: --spp must be at least 1");
  if (train_count < 0 || train_short_side < 0 || eval_short_side < 0) {
    throw UsageError("evaluate: counts and sizes must not be negative");
  }
  if (metrics.empty()) throw UsageError("evaluate: no metric selected");
  for (metrics::Metric m : error_image_metrics) {
    if (std::find(metrics.begin(), metrics.end(), m) == metrics.end()) {
      throw UsageError(fmt::format("evaluate: --error-image-metrics: {} is not among --metrics",
                                   metrics::MetricName(m)));
    }
  }
  if (projection_metric != "none" && !metrics::ParseMetric(projection_metric)) {
    throw UsageError(fmt::format("evaluate: unknown projection metric '{}'", projection_metric));
  }
  if (!only.empty()) ParseTask(only);  // UsageError when malformed
  if (executor != "local" && executor != "slurm") {
    throw UsageError(fmt::format("evaluate: --executor '{}' is not one of local, slurm", executor));
  }
  if (executor == "slurm" && !only.empty()) {
    throw UsageError("evaluate: --only runs one task here; it does not go with --executor slurm");
  }
  compare::CompareOptions c;
  c.photos = c.renders = c.out = "-";
  c.metrics = metrics;
  c.metric_options = metric_options;
  c.exposure = exposure;
  try {
    c.Check();
  } catch (const Error& e) {
    throw UsageError(e.what());
  }
}

EvaluateResult RunEvaluate(const EvaluateOptions& options) {
  RunState s(options);
  std::optional<InterruptGuard> guard;
  if (options.handle_interrupts) guard.emplace();
  RequestInterrupt(false);
  if (options.executor == "slurm") {
    const SlurmRunOutcome outcome = RunEvaluateOnSlurm(options);
    if (!outcome.finished) {
      ThrowError("{}: the Slurm jobs did not finish the run ({}); rerun to resume",
                 options.out.string(),
                 outcome.failed.empty() ? "not waited for" : outcome.failed.front());
    }
    return outcome.result;
  }
  try {
    return options.only.empty() ? RunAll(s) : RunTask(s);
  } catch (const Error& e) {
    // run.json's status becomes "failed" with the message (an interrupted run keeps
    // "interrupted"); nothing is written before the run folder is this scene's.
    if (s.run_json_ours && !InterruptRequested()) {
      s.failure = e.what();
      try {
        WriteRunJson(s, nullptr, "failed");
      } catch (const std::exception&) {
        // The original error is the one to report.
      }
    }
    throw;
  }
}

std::vector<metrics::Metric> ErrorImageMetrics(const EvaluateOptions& options) {
  std::vector<metrics::Metric> list = options.error_image_metrics;
  if (list.empty()) return list;  // all
  const std::optional<metrics::Metric> projected = metrics::ParseMetric(options.projection_metric);
  if (projected &&
      std::find(options.metrics.begin(), options.metrics.end(), *projected) !=
          options.metrics.end() &&
      std::find(list.begin(), list.end(), *projected) == list.end()) {
    list.push_back(*projected);
  }
  return list;
}

}  // namespace rephoto::eval
