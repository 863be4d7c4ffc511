#include "slurm_args.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <memory>

#include "rephoto/cluster/slurm_settings.h"
#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"

namespace rephoto::cli {

void AddExecutorOptions(CLI::App& app, ExecutorArguments* args) {
  const std::string group = "Cluster (docs/cluster.md)";
  app.add_option("--executor", args->executor,
                 "Where the work runs: local (this process) or slurm (job arrays through sbatch; "
                 "the run folder must be on a filesystem the nodes share)")
      ->check(CLI::IsMember({"local", "slurm"}))
      ->capture_default_str()
      ->group(group);
  CLI::Option* wait = app.add_flag("--wait,!--no-wait", args->wait,
                                   "slurm: follow the jobs until they finish (default), or return "
                                   "after submitting and print the job ids; running the same "
                                   "command again collects and resumes")
                          ->group(group);
  args->slurm_only.push_back(wait);
  for (const cluster::SlurmSettingInfo& info : cluster::SlurmSettings()) {
    std::vector<std::string>& values = args->slurm[info.name];
    CLI::Option* option = app.add_option("--slurm-" + info.name, values, info.help)->group(group);
    if (info.repeatable) {
      option->allow_extra_args(false)->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
    } else {
      option->expected(1)->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
    }
    args->slurm_only.push_back(option);
  }
}

std::optional<cluster::SlurmOptions> MakeSlurmOptions(const ExecutorArguments& args,
                                                      cluster::SlurmOptions base) {
  if (args.executor != "slurm") {
    for (const CLI::Option* option : args.slurm_only) {
      const std::string name = option->get_name();
      REPHOTO_CHECK_USAGE(option->count() == 0, "{} needs --executor slurm",
                          name == "--wait" ? "--wait/--no-wait" : name);
    }
    return std::nullopt;
  }
  for (const cluster::SlurmSettingInfo& info : cluster::SlurmSettings()) {
    const auto found = args.slurm.find(info.name);
    if (found == args.slurm.end()) continue;
    for (const std::string& value : found->second) {
      cluster::SetSlurmSetting(base, info.name, value, "--slurm-" + info.name);
    }
  }
  base.wait = args.wait;
  cluster::SlurmOptions options = cluster::ResolveReconstructResources(std::move(base));
  options.Check();
  return options;
}

void PrintSlurmOutcome(const cluster::RunOutcome& outcome, const std::string& resume_hint) {
  std::vector<std::string> submitted, followed;
  for (const cluster::GroupOutcome& group : outcome.groups) {
    for (const std::string& job : group.submitted_jobs) {
      submitted.push_back(fmt::format("{} ({})", job, group.name));
    }
    for (const std::string& job : group.followed_jobs) {
      followed.push_back(fmt::format("{} ({})", job, group.name));
    }
  }
  if (!submitted.empty()) {
    LogInfo(fmt::format("slurm: submitted {} task(s) as job(s) {}", outcome.submitted,
                        fmt::join(submitted, ", ")));
  }
  if (!followed.empty()) {
    LogInfo(
        fmt::format("slurm: following job(s) submitted earlier: {}", fmt::join(followed, ", ")));
  }
  for (const std::string& line : outcome.FailureLines()) LogWarning("slurm: failed: " + line);
  if (!outcome.finished) {
    // Not a log line (not silenced by -q): scripts read the job ids from stdout.
    fmt::print("slurm jobs: {}\n", fmt::join(outcome.JobIds(), " "));
    std::fflush(stdout);
    LogInfo(
        fmt::format("slurm: the jobs run on; run `{}` again to follow them and collect the "
                    "results",
                    resume_hint));
  }
}

}  // namespace rephoto::cli
