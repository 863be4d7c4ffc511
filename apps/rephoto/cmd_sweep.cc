// rephoto sweep CONFIG [--out DIR]
// Runs `rephoto evaluate` over a grid of settings (defect strengths, training-set sizes,
// training resolutions) described by a TOML/JSON file; see src/rephoto/sweep/sweep.h.
#include <fmt/format.h>

#include <memory>
#include <string>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"
#include "rephoto/sweep/sweep.h"
#include "slurm_args.h"

namespace rephoto::cli {
namespace {

struct SweepArguments {
  std::string config;
  std::string out;
  bool no_report = false;
  bool only_aggregate = false;
  int views_per_task = 16;
  ExecutorArguments executor;
};

CommandRunner SetupSweep(CLI::App& app) {
  auto args = std::make_shared<SweepArguments>();
  app.add_option("CONFIG", args->config,
                 "Experiment file (.toml or .json): evaluate settings plus a [sweep] table")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--out", args->out, "Output folder (default: the config's [sweep] out)");
  app.add_flag("--no-report", args->no_report, "Do not write report.html");
  app.add_flag("--only-aggregate", args->only_aggregate,
               "Only write the sweep's tables, report and sweep.json from the settings' run "
               "folders (the last task of --executor slurm)");
  app.add_option("--views-per-task", args->views_per_task,
                 "Held-out views per Slurm task (--executor slurm)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  AddExecutorOptions(app, &args->executor);
  return [args] {
    sweep::SweepOptions options = sweep::LoadSweepConfig(args->config);
    if (!args->out.empty()) options.out = args->out;
    if (args->no_report) options.report = false;
    options.only_aggregate = args->only_aggregate;
    options.base.handle_interrupts = true;
    options.base.views_per_task = args->views_per_task;
    const std::optional<cluster::SlurmOptions> slurm =
        MakeSlurmOptions(args->executor, options.base.slurm);
    if (slurm) {
      options.base.executor = eval::Executor::kSlurm;
      options.base.slurm = *slurm;
    }
    const sweep::SweepResult result = sweep::RunSweep(options);
    if (options.base.executor == eval::Executor::kSlurm) {
      PrintSlurmOutcome(result.slurm, "rephoto sweep ... (the same command)");
      if (!result.slurm_finished) {
        return static_cast<int>(result.slurm.finished ? ExitCode::kIncomplete : ExitCode::kOk);
      }
      LogInfo(fmt::format("sweep: {} settings -> {}", result.settings.size(),
                          (options.out / "sweep.csv").string()));
      return static_cast<int>(result.slurm.FailureLines().empty() ? result.exit_code
                                                                  : ExitCode::kIncomplete);
    }
    LogInfo(fmt::format(
        "sweep: {} settings in {:.1f} s (pipeline {:.1f} s, rephoto {:.1f} s = {:.1f} %; CPU: "
        "pipeline {:.1f} s, rephoto {:.1f} s = {:.1f} %) -> {}",
        result.settings.size(), result.total_seconds, result.external_seconds,
        result.rephoto_seconds, 100 * result.rephoto_share(), result.external_cpu_seconds,
        result.rephoto_cpu_seconds, 100 * result.rephoto_cpu_share(),
        (options.out / "sweep.csv").string()));
    return static_cast<int>(result.exit_code);
  };
}

REPHOTO_COMMAND(65, "sweep",
                "Evaluate over a grid of settings (defects, |T|, training resolution); one table "
                "and report",
                SetupSweep);

}  // namespace
}  // namespace rephoto::cli
