// The Slurm settings of `--executor slurm`, by name, for the command line and for config files.
//
// Each setting NAME is the flag --slurm-NAME and the key NAME of a config file's [slurm] table
// (e.g. `--slurm-time 2:00:00` or `[slurm] time = "2:00:00"`):
//   partition, time, mem, account, qos, cpus-per-task, option (repeatable: one sbatch argument
//   each)    resources of rephoto's own tasks (rendering, comparing, aggregating);
//   reconstruct-partition, ..., reconstruct-option
//            resources of the user's reconstruction commands; every one left unset takes the
//            value of the setting without "reconstruct-", and reconstruct-option adds to option;
//   max-running (tasks of one array at once, 0 = no limit), poll (seconds between squeue calls).
// Thread safety: reentrant.
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/cluster/slurm.h"

namespace rephoto::cluster {

struct SlurmSettingInfo {
  std::string name;  // "time", "reconstruct-time", ...
  std::string help;  // one line for --help
  bool repeatable = false;
};

// All settings, in the order --help lists them.
const std::vector<SlurmSettingInfo>& SlurmSettings();

// Sets one setting from its text; a repeatable one appends. `where` names the source in
// messages ("--slurm-time", "exp.toml: [slurm] time"). Throws UsageError "<where>: <why>" for an
// unknown name or a bad value (a time that is not Slurm's syntax, a negative count).
void SetSlurmSetting(SlurmOptions& options, std::string_view name, const std::string& value,
                     std::string_view where);

// Applies a config file's [slurm] table, as JSON (eval::LoadConfigFile returns extra tables so):
// keys as above ('_' and '-' are the same), values strings or numbers, and arrays of strings
// for the repeatable ones. Throws UsageError "<file>: [slurm] <key>: <why>" for an unknown key
// or a value of the wrong type; `file` names the config file.
void ApplySlurmTable(SlurmOptions& options, const nlohmann::json& table, std::string_view file);

// `options` with the reconstruction resources completed from the work resources (see above).
SlurmOptions ResolveReconstructResources(SlurmOptions options);

}  // namespace rephoto::cluster
