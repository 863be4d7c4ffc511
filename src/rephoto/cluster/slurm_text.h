// The text rephoto exchanges with Slurm: batch scripts and sbatch arguments it writes, and the
// output of sbatch, squeue, sacct and scontrol it reads; plus the result files its batch
// scripts write. Pure functions (no Slurm needed), used by slurm.cc and tested on their own.
//
// Output formats read (Slurm 22.05 and later; the same in 20.11 and 23.x):
//   sbatch --parsable            "<job id>" or "<job id>;<cluster>"
//   squeue -h -r -t all -o '%F|%K|%T|%r|%N'
//                                "<array job id>|<array index>|<STATE>|<reason>|<node list>"
//   sacct -n -X -P -o JobID,State,ExitCode,NodeList
//                                "<job>_<index>|<STATE>[ by <uid>]|<code>:<signal>|<nodes>"
//   scontrol show config         "MaxArraySize            = 1001"
// Thread safety: all functions are reentrant.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/cluster/slurm.h"
#include "rephoto/core/process.h"

namespace rephoto::cluster {

// Throws UsageError "task id '<id>': <why>" unless id is valid (see Task::id).
void CheckTaskId(std::string_view id);
// Throws UsageError "task group '<name>': <why>" unless name matches [a-z0-9_-]{1,64}.
void CheckGroupName(std::string_view name);

// `value` as one POSIX shell word (core/process.h ShellQuote, the project's one quoting rule).

// 32 hex digits (XXH3-128) of the task's argv and key: what identifies its work.
std::string TaskFingerprint(const Task& task);

// Where a task's result file lives: <slurm_dir>/results/<id>.json.
std::filesystem::path ResultPath(const std::filesystem::path& slurm_dir, std::string_view id);

// One array submission: its tasks in array-index order.
struct ArraySpec {
  int submission = 0;               // sequence number in the run (1, 2, ...)
  std::string group;                // TaskGroup::name
  std::filesystem::path slurm_dir;  // absolute RUN/slurm
  std::vector<const Task*> tasks;   // array index i runs tasks[i]
  const SlurmResources* resources = nullptr;
  std::string job_name;                 // --job-name
  int max_running = 0;                  // "%N" throttle; 0: none
  std::vector<std::string> after_jobs;  // array job ids for --dependency=afterany
};

// The batch script of an array: a /bin/sh script that maps $SLURM_ARRAY_TASK_ID to a task,
// runs its argv, and writes its result file atomically when the argv exits (the script exits
// with the argv's code, so Slurm reports the task COMPLETED or FAILED as it did).
std::string MakeArrayScript(const ArraySpec& spec, const std::vector<std::string>& sbatch_argv);

// The sbatch arguments after the program name, ending with the script path:
// --parsable --job-name --array --output (<slurm_dir>/%A_%a.log) [--open-mode=append]
// [resources] [--dependency=afterany:J1:J2] [resources.options...] SCRIPT.
std::vector<std::string> SbatchArguments(const ArraySpec& spec,
                                         const std::filesystem::path& script);

// The job id in `sbatch --parsable` output; throws Error "sbatch: unexpected output '<text>'"
// when it holds none.
std::string ParseSbatchJobId(std::string_view output);

// One array task as squeue or sacct lists it.
struct QueueEntry {
  std::string array_job;  // the array's job id
  int index = -1;         // the array index
  std::string state;      // PENDING, RUNNING, COMPLETED, FAILED, CANCELLED, TIMEOUT, ...
  std::string reason;     // squeue: why it is pending ("Dependency", "Resources"); sacct: ""
  std::string node;       // node list ("" when none yet)
  int exit_code = -1;     // sacct: the batch script's exit code; -1 when unknown
  int signal = 0;         // sacct: the signal that ended it
};

// Parses squeue output in the format above. Lines that are not array tasks (a plain job, a
// pending range "123_[4-9]") are skipped.
std::vector<QueueEntry> ParseSqueue(std::string_view output);
// Parses sacct output in the format above (the same rules).
std::vector<QueueEntry> ParseSacct(std::string_view output);
// The job id in `squeue -h -t all --name NAME -o '%F|%o'` output whose command is `script`.
std::optional<std::string> FindJobOfScript(std::string_view output, std::string_view script);
// MaxArraySize from `scontrol show config`; nullopt when absent or not a number.
std::optional<int> ParseMaxArraySize(std::string_view output);

// True for the states of a task that may still run or is running: PENDING, CONFIGURING,
// RUNNING, COMPLETING, SUSPENDED, REQUEUED, REQUEUE_HOLD, REQUEUE_FED, RESIZING, SIGNALING,
// STAGE_OUT, STOPPED.
bool IsActiveState(std::string_view state);
// True for a pending reason (squeue %r) that needs a person rather than time: JobHeldUser,
// JobHeldAdmin, "launch failed requeued held", DependencyNeverSatisfied, BadConstraints,
// InvalidAccount, InvalidQOS.
bool IsStuckReason(std::string_view reason);
// "cancelled", "timed out", "ran out of memory", "node failed", ... for a final Slurm state.
std::string DescribeFinalState(std::string_view state);

// A result file written by the batch script.
struct TaskResult {
  std::string id;
  std::string fingerprint;
  int submission = 0;
  std::string job;  // array job id
  int index = -1;   // array index
  std::string node;
  int exit_code = -1;
  std::string start, end;  // UTC, ISO 8601
  double seconds = 0;
};
// Parses a result file's text; nullopt when it is not one (a partial or foreign file).
std::optional<TaskResult> ParseTaskResult(std::string_view json);

}  // namespace rephoto::cluster
