#include "rephoto/eval/slurm_executor.h"

#include <unistd.h>

#include <set>

#include "rephoto/cluster/slurm_settings.h"
#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/eval/command_template.h"
#include "rephoto/eval/hash.h"
#include "rephoto/eval/result_text.h"
#include "rephoto/eval/settings.h"
#include "rephoto/run/records.h"

namespace rephoto::eval {
namespace fs = std::filesystem;

fs::path ThisExecutable() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  REPHOTO_CHECK(!ec, "cannot find this program's path (/proc/self/exe): {}", ec.message());
  return exe;
}

namespace {

// The argv of one task on a node.
// Threads: the job's CPUs ($SLURM_CPUS_PER_TASK, which main.cc honours without -j).
std::vector<std::string> TaskArgv(const fs::path& program, const fs::path& config,
                                  const std::string& task) {
  std::vector<std::string> argv = {program.string(), "-q"};
  argv.insert(argv.end(), {"evaluate", "--config", config.string(), "--only", task});
  return argv;
}

std::vector<cluster::TaskGroup> TaskGroups(const EvaluateOptions& o, const EvaluatePlan& plan,
                                           const fs::path& program, const fs::path& config,
                                           const std::string& config_key,
                                           const std::string& prefix = "") {
  cluster::TaskGroup folds{"fold", {}, o.source() != ModelSource::kModel};
  cluster::TaskGroup views{"views", {}, false};
  cluster::TaskGroup aggregate{"aggregate", {}, false};
  std::set<size_t> submitted_folds;
  for (const EvaluateTask& task : plan.tasks) {
    if (task.done) continue;
    cluster::Task t{prefix + task.id, TaskArgv(program, config, task.id),
                    Hasher().Add(config_key).Add(task.key).Hex(), std::nullopt};
    if (task.kind == EvaluateTask::Kind::kFold) {
      t.after = std::vector<std::string>();
      folds.tasks.push_back(std::move(t));
      submitted_folds.insert(task.fold);
    } else if (task.kind == EvaluateTask::Kind::kViews) {
      t.after = std::vector<std::string>();
      if (submitted_folds.count(task.fold)) {
        t.after->push_back(fmt::format("{}fold:{}", prefix, task.fold));
      }
      views.tasks.push_back(std::move(t));
    } else {
      aggregate.tasks.push_back(std::move(t));
    }
  }
  return {folds, views, aggregate};
}

}  // namespace

std::vector<cluster::TaskGroup> PrepareEvaluateTasks(const EvaluateOptions& options,
                                                     const std::string& prefix,
                                                     const PlanFunction& plan_evaluate,
                                                     EvaluatePlan* plan) {
  options.Check();
  REPHOTO_CHECK_USAGE(options.views_per_task >= 1, "evaluate: --views-per-task must be >= 1");
  const fs::path program = options.program.empty() ? ThisExecutable() : options.program;
  REPHOTO_CHECK_USAGE(program.is_absolute(),
                      "evaluate: the rephoto program path {} is not absolute", program.string());
  *plan = plan_evaluate(options, static_cast<size_t>(options.views_per_task));
  // The settings as a config file every task reads (absolute paths: nodes share the paths).
  EvaluateOptions task_options = options;
  task_options.out = plan->run;
  const fs::path config = plan->run / "evaluate-settings.json";
  const std::string config_text = SettingsJson(task_options).dump(2) + "\n";
  WriteTextFileAtomically(config, config_text);
  const std::string config_key = Hasher().Add(config_text).Hex();
  return TaskGroups(options, *plan, program, config, config_key, prefix);
}

SlurmRunOutcome RunEvaluateOnSlurm(const EvaluateOptions& options,
                                   const PlanFunction& plan_evaluate) {
  EvaluatePlan plan;
  const std::vector<cluster::TaskGroup> groups =
      PrepareEvaluateTasks(options, "", plan_evaluate, &plan);
  SlurmRunOutcome outcome;
  outcome.tasks = plan.tasks.size();
  for (const EvaluateTask& task : plan.tasks) outcome.tasks_done_before += task.done ? 1 : 0;
  cluster::SlurmOptions slurm = cluster::ResolveReconstructResources(options.slurm);
  slurm.interrupted = [] { return InterruptRequested(); };
  slurm.job_name = "rephoto-eval";
  // The plan's keys say what is unfinished (a task whose outputs were deleted runs again).
  slurm.skip_succeeded = false;
  LogInfo(fmt::format("evaluate on Slurm: {} folds, {} views, {} tasks ({} done before) -> {}",
                      plan.folds, plan.views, plan.tasks.size(), outcome.tasks_done_before,
                      plan.run.string()));
  const cluster::RunOutcome run =
      cluster::RunTaskGroups(plan.run, groups, slurm, cluster::ProgressLogger());
  outcome.run = run;
  outcome.jobs = run.JobIds();
  outcome.failed = run.FailureLines();
  outcome.submitted = run.submitted;
  const bool aggregated =
      outcome.tasks_done_before == outcome.tasks ||
      (!groups[2].tasks.empty() && run.groups.size() == 3 && !run.groups[2].tasks.empty() &&
       run.groups[2].tasks[0].state == cluster::TaskState::kDone);
  outcome.finished = run.finished && aggregated;
  if (outcome.finished) outcome.result = ReadEvaluateResult(plan.run);
  if (!outcome.failed.empty()) outcome.result.exit_code = ExitCode::kIncomplete;
  return outcome;
}

}  // namespace rephoto::eval
