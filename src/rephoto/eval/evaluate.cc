// Sequences the stages of `rephoto evaluate` (eval/state.h lists them) for a whole run, or for
// one task of a run (EvaluateOptions::only) as an executor on another machine runs it. Each
// stage is a call with typed inputs and outputs; this file only decides their order and
// threads, and where a failure stops a fold or the run.
#include "rephoto/eval/evaluate.h"

#include <atomic>
#include <condition_variable>
#include <mutex>
#include <thread>

#include "rephoto/core/file.h"
#include "rephoto/core/process.h"
#include "rephoto/core/progress.h"
#include "rephoto/eval/aggregate.h"
#include "rephoto/eval/command_template.h"
#include "rephoto/eval/fold_model.h"
#include "rephoto/eval/inputs.h"
#include "rephoto/eval/prepare_fold.h"
#include "rephoto/eval/projection.h"
#include "rephoto/eval/rephoto_views.h"
#include "rephoto/eval/run_command.h"
#include "rephoto/eval/run_records.h"
#include "rephoto/eval/settings.h"
#include "rephoto/eval/slurm_executor.h"
#include "rephoto/eval/state.h"
#include "rephoto/split/split_writer.h"

namespace rephoto::eval {
namespace fs = std::filesystem;

namespace {

// What the sequencer holds for one invocation: the run (const for the stages once started), the
// folds' plans and outcomes (by fold index), what the stages did and run.json's status.
struct Run {
  RunContext context;
  std::vector<FoldPlan> plans;
  std::vector<FoldOutcome> folds;
  Tally tally;
  RunStatus status;
};

void WriteRunJson(const Run& r, const EvaluateResult* result, const std::string& status) {
  WriteRunJson(r.context, r.plans, r.tally, r.status, result, status);
}

// The fold takes its command's failure (an interrupted command fails nothing: the run stops).
void TakeCommand(FoldOutcome& fold, CommandOutcome command) {
  fold.command = std::move(command);
  if (!fold.command.ok && !fold.command.interrupted) FailFold(fold, fold.command.message);
}

// The rephoto stage of one fold: its model, which views need work, the renderer when one does,
// then render and compare them.
void RephotoFold(Run& r, ViewWorkspace& ws, size_t f, Progress* progress, size_t first = 0,
                 size_t count = 0) {
  const RunContext& s = r.context;
  const FoldPlan& plan = r.plans[f];
  FoldOutcome& fold = r.folds[f];
  const auto start = Clock::now();
  std::optional<mesh::Mesh> mesh;  // read by ResolveFoldModel unless its key was known
  ResolveFoldModel(s, plan, fold.command, ws.models, &mesh, &fold.model);
  const std::vector<size_t> todo =
      PlanViews(s, plan, fold.model, fold.views, r.tally, progress, first, count);
  bool need_renderer = false;
  for (size_t i : todo) {
    need_renderer |= s.source != ModelSource::kRender && !fold.views[i].reuse_render;
  }
  FoldTrainingScene training(s, plan);
  std::unique_ptr<render::ViewRenderer> renderer;
  if (need_renderer) {
    renderer = MakeFoldRenderer(s, plan, fold.model, training, ws.models, &mesh, r.tally);
  }
  if (!s.worker) WriteFoldJson(s, plan, fold, "running");
  EvaluateViews(s, ws, plan, fold.model, todo, renderer.get(), fold.views, r.tally, progress);
  fold.seconds = Seconds(start);
}

// The common start of every invocation: settings, inputs, run folder, split, folds.
void Start(const EvaluateOptions& options, Run& r) {
  RunContext& s = r.context;
  s.start = Clock::now();
  s.start_cpu = ProcessCpuSeconds();
  options.Check();
  s.options = options;
  s.source = options.source();
  s.run = fs::absolute(options.out).lexically_normal();
  s.worker = !options.only.empty();
  if (s.source == ModelSource::kModel && !options.model.empty()) {
    std::error_code ec;
    REPHOTO_CHECK(fs::is_regular_file(options.model, ec), "{}: no such model file (--model)",
                  options.model.string());
  }
  const auto phase = Clock::now();
  ReadInputs(s);
  OpenRun(s, r.tally, r.status);
  MakeSplit(s);
  if (!s.worker) WriteRunJson(r, nullptr, "running");
  r.tally.AddSeconds(&EvaluateTimings::split, Seconds(phase));
  // Named but not yet planned (PrepareFold plans each).
  r.plans.resize(s.split.folds.size());
  for (size_t f = 0; f < r.plans.size(); ++f) {
    r.plans[f].index = f;
    r.plans[f].name = split::FoldFolderName(f, r.plans.size());
  }
  r.folds.resize(r.plans.size());
}

void PrepareFolds(Run& r) {
  const auto phase = Clock::now();
  for (size_t f = 0; f < r.plans.size(); ++f) r.plans[f] = PrepareFold(r.context, f, r.tally);
  if (!r.context.worker) RemoveStaleOutputs(r.context, r.plans);
  r.tally.AddSeconds(&EvaluateTimings::prepare, Seconds(phase));
}

// Aggregation, manifest, run.json, the shared model's projection and the report.
EvaluateResult Finish(Run& r, ViewWorkspace& ws, ProjectionPlan& projection) {
  const RunContext& s = r.context;
  EvaluateResult result;
  result.missing_photos = s.missing_photos;
  Aggregate(s, r.plans, r.folds, r.tally, &result);
  WriteManifest(s, r.plans, r.folds);
  bool incomplete = !s.missing_photos.empty();
  for (const FoldResult& fr : result.folds) incomplete |= !fr.ok;
  result.exit_code = incomplete ? ExitCode::kIncomplete : ExitCode::kOk;
  const std::string status = incomplete ? "incomplete" : "ok";
  WriteRunJson(r, &result, status);  // the report reads it
  ProjectSharedModel(s, ws.models, projection, r.plans, r.folds, r.tally, r.status);
  WriteReport(s, r.tally, r.status);
  result.counters = r.tally.counters();
  result.timings = r.tally.timings();
  result.timings.total = Seconds(s.start);
  result.timings.rephoto_cpu = ProcessCpuSeconds() - s.start_cpu;
  WriteRunJson(r, &result, status);
  result.timings.total = Seconds(s.start);
  return result;
}

// Runs the folds' commands in background threads, `jobs` at a time, in fold order; the calling
// thread waits for each fold's command in turn (WaitFor) and does the rephoto stage meanwhile.
// A worker writes only its fold's CommandOutcome (and status); the Tally locks.
class CommandPool {
 public:
  explicit CommandPool(Run& r)
      : r_(r), done_(r.plans.size(), r.context.source == ModelSource::kModel ? 1 : 0) {
    if (r.context.source == ModelSource::kModel) return;
    const int count = std::min<int>(r.context.options.jobs, static_cast<int>(r.plans.size()));
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
      if (f >= r_.plans.size()) return;
      const FoldPlan& plan = r_.plans[f];
      FoldOutcome& fold = r_.folds[f];
      if (InterruptRequested() || stop_) {
        fold.command.interrupted = true;
      } else {
        try {
          TakeCommand(fold, RunFoldCommand(r_.context, plan, /*may_run=*/true, r_.tally));
        } catch (const Error& e) {
          fold.command.ok = false;
          FailFold(fold, fmt::format("{}: {}", plan.name, e.what()));
        }
      }
      {
        std::lock_guard<std::mutex> lock(mutex_);
        done_[f] = 1;
      }
      done_cv_.notify_all();
    }
  }

  Run& r_;
  std::mutex mutex_;
  std::condition_variable done_cv_;
  std::vector<char> done_;
  std::vector<std::thread> workers_;
  std::atomic<size_t> next_{0};
  std::atomic<bool> stop_{false};
};

// The rephoto stage of every fold, overlapping the commands of the next folds.
void RephotoAllFolds(Run& r, ViewWorkspace& ws, ProjectionPlan& projection, CommandPool& pool) {
  size_t total_views = 0;
  for (const FoldPlan& plan : r.plans) total_views += plan.tests.size();
  Progress progress("evaluate", total_views);
  for (size_t f = 0; f < r.plans.size(); ++f) {
    const FoldPlan& plan = r.plans[f];
    FoldOutcome& fold = r.folds[f];
    pool.WaitFor(f);
    if (InterruptRequested() || fold.command.interrupted) break;
    if (fold.command.reused) r.tally.Count(&EvaluateCounters::folds_reused);
    if (fold.ok) {
      try {
        RephotoFold(r, ws, f, &progress);
      } catch (const UsageError&) {
        throw;
      } catch (const Error& e) {
        const std::string what = e.what();
        FailFold(fold, what.rfind(plan.name + ":", 0) == 0 ? what : plan.name + ": " + what);
      }
    }
    if (!fold.ok) {
      LogWarning(fold.message);
      for (const TestView& test : plan.tests) {
        progress.Advance(fmt::format("{} {} (fold failed)", plan.name, test.stem));
      }
    }
    WriteFoldJson(r.context, plan, fold, fold.ok ? "ok" : "failed");
    if (!InterruptRequested()) {  // while its model is in memory
      ProjectFold(r.context, ws.models, projection, plan, fold, r.plans.size(), r.tally, r.status);
    }
  }
}

EvaluateResult RunAll(const EvaluateOptions& options, Run& r) {
  Start(options, r);
  PrepareFolds(r);
  const RunContext& s = r.context;
  size_t total_views = 0;
  for (const FoldPlan& plan : r.plans) total_views += plan.tests.size();
  LogInfo(fmt::format("evaluate: {} photos ({} missing), {} folds ({}), {} test views -> {}",
                      s.photo_names.size(), s.missing_photos.size(), r.plans.size(),
                      s.split.scheme.ToString(), total_views, s.run.string()));
  ViewWorkspace ws;
  ProjectionPlan projection;
  {
    CommandPool pool(r);
    RephotoAllFolds(r, ws, projection, pool);
    pool.Join();
  }
  s.hashes->Save();
  if (InterruptRequested()) {
    WriteRunJson(r, nullptr, "interrupted");
    throw Interrupted(fmt::format(
        "{}: interrupted; finished folds and views are kept: rerun the same command to resume",
        s.run.string()));
  }
  return Finish(r, ws, projection);
}

// ------------------------------------------------------------------------------ tasks

// A fold's finished command (never run here): reused, or the fold fails with the recorded reason.
void ReuseFoldCommand(Run& r, size_t f) {
  if (r.context.source == ModelSource::kModel) return;
  const FoldPlan& plan = r.plans[f];
  FoldOutcome& fold = r.folds[f];
  TakeCommand(fold, RunFoldCommand(r.context, plan, /*may_run=*/false, r.tally));
  if (!fold.ok && plan.previous && !plan.previous->value("message", "").empty()) {
    fold.message = plan.previous->value("message", "");
  }
}

// fold:F: the fold's command and its derived model (colours, defects).
ExitCode RunFoldTask(Run& r, size_t f) {
  const RunContext& s = r.context;
  r.plans[f] = PrepareFold(s, f, r.tally);
  const FoldPlan& plan = r.plans[f];
  FoldOutcome& fold = r.folds[f];
  if (s.source != ModelSource::kModel) {
    TakeCommand(fold, RunFoldCommand(s, plan, /*may_run=*/true, r.tally));
    if (fold.command.interrupted) {
      throw Interrupted(fmt::format("{} {}: interrupted", s.run.string(), plan.name));
    }
  }
  if (fold.ok && s.source != ModelSource::kRender) {
    ViewWorkspace ws;
    std::optional<mesh::Mesh> mesh;
    try {
      ResolveFoldModel(s, plan, fold.command, ws.models, &mesh, &fold.model);
      if (s.DerivesModel() && !fold.model.gaussians) {
        FoldTrainingScene training(s, plan);
        LoadFoldModel(s, plan, fold.model, training, ws.models, &mesh, r.tally);
      }
    } catch (const UsageError&) {
      throw;
    } catch (const Error& e) {
      FailFold(fold, fmt::format("{}: {}", plan.name, e.what()));
    }
  }
  WriteFoldJson(s, plan, fold, fold.ok ? "ok" : "failed");
  if (!fold.ok) LogWarning(fold.message);
  return fold.ok ? ExitCode::kOk : ExitCode::kIncomplete;
}

// views:F:FIRST:COUNT: render and compare those views of a fold whose command is finished.
ExitCode RunViewsTask(Run& r, size_t f, size_t first, size_t count) {
  const RunContext& s = r.context;
  r.plans[f] = PrepareFold(s, f, r.tally);
  const FoldPlan& plan = r.plans[f];
  FoldOutcome& fold = r.folds[f];
  ReuseFoldCommand(r, f);
  if (!fold.ok) {
    LogWarning(fold.message);
    return ExitCode::kIncomplete;
  }
  ViewWorkspace ws;
  const size_t end = std::min(plan.tests.size(), first + count);
  Progress progress("evaluate", end > first ? end - first : 0);
  try {
    RephotoFold(r, ws, f, &progress, first, count);
  } catch (const UsageError&) {
    throw;
  } catch (const Error& e) {
    if (InterruptRequested()) throw;
    LogWarning(fmt::format("{}: {}", plan.name, e.what()));
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
EvaluateResult RunAggregateTask(Run& r) {
  const RunContext& s = r.context;
  PrepareFolds(r);
  ViewWorkspace ws;
  ProjectionPlan projection;
  for (size_t f = 0; f < r.plans.size(); ++f) {
    const FoldPlan& plan = r.plans[f];
    FoldOutcome& fold = r.folds[f];
    ReuseFoldCommand(r, f);
    if (!fold.ok) continue;
    try {
      std::optional<mesh::Mesh> mesh;
      ResolveFoldModel(s, plan, fold.command, ws.models, &mesh, &fold.model);
      PlanViews(s, plan, fold.model, fold.views, r.tally, nullptr);
      for (ViewOutcome& view : fold.views) {
        if (!view.reused) view.message = fmt::format("{} {}: not evaluated", plan.name, view.stem);
      }
      if (s.source != ModelSource::kModel && !fold.model.gaussians && s.DerivesModel()) {
        // The model the errors are projected onto.
        FoldTrainingScene training(s, plan);
        LoadFoldModel(s, plan, fold.model, training, ws.models, &mesh, r.tally);
      }
      ProjectFold(s, ws.models, projection, plan, fold, r.plans.size(), r.tally, r.status);
    } catch (const UsageError&) {
      throw;
    } catch (const Error& e) {
      FailFold(fold, fmt::format("{}: {}", plan.name, e.what()));
    }
  }
  s.hashes->Save();
  return Finish(r, ws, projection);
}

EvaluateResult RunTask(const EvaluateOptions& options, Run& r) {
  const TaskSpec task = ParseTaskSpec(options.only);
  Start(options, r);
  EvaluateResult result;
  if (task.kind == EvaluateTask::Kind::kAggregate) {
    // The task did its work when the tables are written; whether the run is complete is in
    // summary.json (the submitting process reads it back).
    result = RunAggregateTask(r);
    result.exit_code = ExitCode::kOk;
    return result;
  }
  REPHOTO_CHECK_USAGE(task.fold < r.plans.size(), "--only {}: the run has {} folds", options.only,
                      r.plans.size());
  result.exit_code = task.kind == EvaluateTask::Kind::kFold
                         ? RunFoldTask(r, task.fold)
                         : RunViewsTask(r, task.fold, task.first, task.count);
  return result;
}

// Whether a fold's task (command, derived model) has its results; fills the fold's model keys.
bool FoldReady(Run& r, ViewWorkspace& ws, size_t f) {
  const RunContext& s = r.context;
  const FoldPlan& plan = r.plans[f];
  FoldOutcome& fold = r.folds[f];
  if (s.source != ModelSource::kModel) {
    TakeCommand(fold, RunFoldCommand(s, plan, /*may_run=*/false, r.tally));
    if (!fold.ok) return false;
  }
  try {
    std::optional<mesh::Mesh> mesh;
    ResolveFoldModel(s, plan, fold.command, ws.models, &mesh, &fold.model);
  } catch (const Error&) {
    return false;  // the fold task reports it
  }
  if (!s.DerivesModel() || fold.model.gaussians) return true;
  std::error_code ec;
  return fs::is_regular_file(plan.derived_model, ec) &&
         fs::is_regular_file(plan.dir / "model.key", ec) &&
         ReadFileToString(plan.dir / "model.key") == fold.model.colorize_key;
}

}  // namespace

EvaluatePlan PlanEvaluate(const EvaluateOptions& options, size_t views_per_task) {
  REPHOTO_CHECK_USAGE(views_per_task > 0, "evaluate: views per task must be at least 1");
  EvaluateOptions o = options;
  o.only.clear();
  o.executor = Executor::kLocal;
  Run r;
  const fs::path run_json = fs::absolute(o.out).lexically_normal() / "run.json";
  const std::optional<Json> previous = run::ReadJsonRecord(run_json);
  const std::string previous_status = previous ? previous->value("status", "") : "";
  Start(o, r);
  PrepareFolds(r);
  const RunContext& s = r.context;
  Hasher settings;
  settings.Add(SettingsJson(o).dump());
  if (s.source == ModelSource::kModel && !o.model.empty()) settings.Add(s.hashes->Hash(o.model));
  const std::string settings_key = settings.Hex();
  EvaluatePlan plan;
  plan.run = s.run;
  plan.folds = r.plans.size();
  ViewWorkspace ws;
  bool all_done = true;
  Hasher aggregate_key;
  aggregate_key.Add(settings_key);
  std::vector<EvaluateTask> view_tasks;
  for (size_t f = 0; f < r.plans.size(); ++f) {
    const FoldPlan& fold_plan = r.plans[f];
    FoldOutcome& fold = r.folds[f];
    plan.views += fold_plan.tests.size();
    const bool fold_task = s.source != ModelSource::kModel || s.DerivesModel();
    const bool ready = FoldReady(r, ws, f);
    const std::string fold_key =
        Hasher().Add(settings_key).Add(fold_plan.train_key).Add(fold_plan.test_key).Hex();
    if (fold_task) {
      plan.tasks.push_back(
          {EvaluateTask::Kind::kFold, fmt::format("fold:{}", f), f, 0, fold_key, ready});
      all_done &= ready;
    }
    const size_t tests = fold_plan.tests.size();
    for (size_t first = 0; first < tests; first += views_per_task) {
      const size_t count = std::min(views_per_task, tests - first);
      EvaluateTask task{EvaluateTask::Kind::kViews, fmt::format("views:{}:{}:{}", f, first, count),
                        f, count};
      Hasher key;
      key.Add(fold_key);
      task.done =
          ready &&
          PlanViews(s, fold_plan, fold.model, fold.views, r.tally, nullptr, first, count).empty();
      for (size_t i = first; i < first + count; ++i) {
        key.Add(fold_plan.tests[i].stem).Add(ready ? fold.views[i].key : std::string());
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

EvaluateResult RunEvaluate(const EvaluateOptions& options) {
  std::optional<InterruptGuard> guard;
  if (options.handle_interrupts) guard.emplace();
  RequestInterrupt(false);
  if (options.executor == Executor::kSlurm) {
    const SlurmRunOutcome outcome = RunEvaluateOnSlurm(options, PlanEvaluate);
    if (!outcome.finished) {
      ThrowError("{}: the Slurm jobs did not finish the run ({}); rerun to resume",
                 options.out.string(),
                 outcome.failed.empty() ? "not waited for" : outcome.failed.front());
    }
    return outcome.result;
  }
  Run r;
  try {
    return options.only.empty() ? RunAll(options, r) : RunTask(options, r);
  } catch (const Error& e) {
    // run.json's status becomes "failed" with the message (an interrupted run keeps
    // "interrupted"); nothing is written before the run folder is this scene's.
    if (r.status.run_json_ours && !InterruptRequested()) {
      r.status.failure = e.what();
      try {
        WriteRunJson(r, nullptr, "failed");
      } catch (const std::exception&) {
        // The original error is the one to report.
      }
    }
    throw;
  }
}

}  // namespace rephoto::eval
