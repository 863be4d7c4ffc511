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

namespace rephoto::cli {
namespace {

struct SweepArguments {
  std::string config;
  std::string out;
  bool no_report = false;
};

CommandRunner SetupSweep(CLI::App& app) {
  auto args = std::make_shared<SweepArguments>();
  app.add_option("CONFIG", args->config,
                 "Experiment file (.toml or .json): evaluate settings plus a [sweep] table")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--out", args->out, "Output folder (default: the config's [sweep] out)");
  app.add_flag("--no-report", args->no_report, "Do not write report.html");
  return [args] {
    sweep::SweepOptions options = sweep::LoadSweepConfig(args->config);
    if (!args->out.empty()) options.out = args->out;
    if (args->no_report) options.report = false;
    options.base.handle_interrupts = true;
    const sweep::SweepResult result = sweep::RunSweep(options);
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
