// Command-line options of `--executor slurm` shared by evaluate and sweep (docs/cluster.md):
// --executor local|slurm, --wait/--no-wait, and every --slurm-NAME of cluster/slurm_settings.h
// (--slurm-partition, --slurm-time, --slurm-mem, --slurm-account, --slurm-qos,
// --slurm-cpus-per-task, --slurm-option, the same with --slurm-reconstruct-..., and
// --slurm-max-running, --slurm-poll).
#pragma once

#include <CLI/CLI.hpp>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "rephoto/cluster/slurm.h"

namespace rephoto::cli {

struct ExecutorArguments {
  std::string executor = "local";
  bool wait = true;
  std::map<std::string, std::vector<std::string>> slurm;  // by setting name, as given
  std::vector<CLI::Option*> slurm_only;                   // the options that need --executor slurm
};

// Declares the options on `app` (group "Cluster"), storing into `args` (which must outlive
// parsing).
void AddExecutorOptions(CLI::App& app, ExecutorArguments* args);

// After parsing. nullopt for --executor local (UsageError when a --slurm-* option or --no-wait
// was given with it); otherwise `base` (e.g. from a config file's [slurm] table, through
// cluster::SetSlurmSetting) with the flags applied over it, the reconstruction resources
// completed from the work resources, and wait set. Throws UsageError naming a bad flag value.
std::optional<cluster::SlurmOptions> MakeSlurmOptions(const ExecutorArguments& args,
                                                      cluster::SlurmOptions base = {});


// Prints what a RunTaskGroups call did: the job ids it submitted or follows, one line per failed
// task (with its log file), and, when it did not wait, how to collect the results later
// (`resume_hint`: the command to run again).
void PrintSlurmOutcome(const cluster::RunOutcome& outcome, const std::string& resume_hint);

}  // namespace rephoto::cli
