// Running groups of rephoto tasks as Slurm job arrays (the `--executor slurm` of evaluate and
// sweep; docs/cluster.md).
//
// A Task is one command line (argv) that runs on a compute node, e.g. `/abs/rephoto -q evaluate
// --config RUN/evaluate-settings.json --only fold:2`. Tasks are idempotent, write their
// outputs atomically, and share nothing with the submitting process but the run folder on a
// shared filesystem. This module knows nothing about what a task does: it runs TaskGroups in
// order, one job array per group (split into several arrays when a group has more tasks than the
// cluster's MaxArraySize), each later group's arrays depending on the earlier groups' active
// jobs with `--dependency=afterany:...`. afterany, not afterok: a failed fold must block neither
// the other folds' work nor the aggregation, which records the failure per fold as a local run
// does; a task that needs an earlier task's output says so in Task::after (below), so it is run
// again when that task is.
//
// Files, all below RUN/slurm/ (the folder is locked while RunTaskGroups runs, run/run_folder.h):
//   jobs.json                       every submission: sequence number, array job id, group,
//                                   sbatch command line, script, tasks by array index
//                                   ("schema": "rephoto.cluster.jobs/1"; written atomically)
//   submit-<seq>-<group>.sh         the array's batch script: array index -> task argv, and the
//                                   wrapper that records the task's result
//   <job>_<index>.log               stdout+stderr of one array task (sbatch %A_%a)
//   results/<task id>.json          written atomically by the wrapper when the task's argv exits:
//                                   id, fingerprint, submission, job, array index, node, exit
//                                   code, start/end (UTC) and seconds
//                                   ("schema": "rephoto.cluster.result/1")
//
// Resume: a task is done when its result file says exit code 0, its fingerprint (argv + key)
// matches, and every task it depends on (Task::after) is done and finished in an earlier
// submission; done tasks are never submitted again. A task that is still pending or running in
// a recorded job is followed, not submitted again (unless a task it depends on is submitted
// again in this call: then it is cancelled and submitted anew after it). A task that failed,
// was cancelled, timed out, ran out of memory or vanished (node died) is submitted again by the
// next call.
//
// Thread safety: RunTaskGroups is reentrant for different run folders; one run folder has one
// submitter at a time (a second gets an Error at once, as a second writer of a run folder does).
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace rephoto::cluster {

// sbatch resources of one kind of task. Empty strings and 0 leave Slurm's (partition's) default.
struct SlurmResources {
  std::string partition;  // --partition
  std::string time;       // --time, in Slurm's syntax: "30" (minutes), "2:00:00", "1-00:00:00"
  std::string mem;        // --mem, per node: "4G", "500M"
  std::string account;    // --account
  std::string qos;        // --qos
  int cpus_per_task = 0;  // --cpus-per-task
  // Further sbatch arguments, each passed to sbatch as one argument, verbatim and after the
  // ones above (so they win): "--constraint=avx512", "--gres=gpu:1", "--exclusive".
  std::vector<std::string> options;
};

// The Slurm client programs. Names without '/' are looked up on PATH.
struct SlurmCommands {
  std::string sbatch = "sbatch";
  std::string squeue = "squeue";
  std::string scancel = "scancel";
  std::string sacct = "sacct";
  std::string scontrol = "scontrol";
  // The defaults, each overridden by a non-empty environment variable REPHOTO_SBATCH,
  // REPHOTO_SQUEUE, REPHOTO_SCANCEL, REPHOTO_SACCT, REPHOTO_SCONTROL (tests use a wrapper
  // that logs and forwards).
  static SlurmCommands FromEnvironment();
};

// Counts of the tasks of one RunTaskGroups call, reported whenever one changes.
struct Progress {
  size_t total = 0;    // tasks in all groups
  size_t done = 0;     // finished with exit code 0 (now or before this call)
  size_t failed = 0;   // finished otherwise (failed, cancelled, timed out, vanished)
  size_t running = 0;  // running (or completing) on a node
  size_t pending = 0;  // waiting in the queue (resources, dependencies)
  // Of the pending ones, those that wait for a person, not for resources: held (a launch
  // failure, `scontrol hold`; `scontrol release` lets them run), a dependency that can never be
  // met, an invalid account, QOS or constraint (squeue's reason). Waiting goes on for them.
  size_t held = 0;
};

struct SlurmOptions {
  SlurmResources work;         // rephoto's own tasks (rendering, comparing, aggregating)
  SlurmResources reconstruct;  // groups with TaskGroup::reconstruct_resources (the user's
                               // reconstruction commands)
  // true: follow the jobs until every task has finished (squeue; sacct, when the cluster keeps
  // accounting, says why a task that left the queue without a result failed). false: return
  // right after submitting.
  bool wait = true;
  double poll_seconds = 2;  // between two squeue calls while waiting (> 0)
  // How long a task that left the queue may take to show its result file before it counts as
  // vanished (NFS attribute caches delay what a node wrote). Seconds, >= 0.
  double result_grace_seconds = 30;
  // true: a task whose result file says exit code 0 for its fingerprint (and whose inputs did
  // not run again) is done and is not submitted (the resume rules above). false: every task
  // given is submitted unless it is pending or running in a recorded job; for callers that pass
  // only the tasks their own records call unfinished (evaluate's plan: the run folder is the
  // truth), so that a task whose outputs were deleted after it succeeded runs again. (A task
  // that succeeds between the caller's look and this call's squeue then runs once more.)
  bool skip_succeeded = true;
  // At most this many tasks of one array at once ("--array=0-99%N"); 0: no limit.
  int max_running = 0;
  // Tasks per array; 0: the cluster's MaxArraySize (scontrol), 1001 if unknown.
  int max_array_size = 0;
  std::string job_name = "rephoto";  // --job-name is "<job_name>-<group>"
  SlurmCommands commands = SlurmCommands::FromEnvironment();
  // Polled while waiting; when it returns true RunTaskGroups throws Interrupted, leaving the
  // jobs queued and running (the message says how to follow or cancel them). Empty: never.
  std::function<bool()> interrupted;
  // Throws UsageError naming the setting when one is invalid.
  void Check() const;
};

struct Task {
  // Unique in the run; also the name of its result file, so it is one or more segments of
  // [A-Za-z0-9_.:+-] (not "." or "..") joined by '/': "fold_02/reconstruct", "views/2/0-7".
  std::string id;
  // The command; argv[0] is an absolute path that is the same on every node (the rephoto
  // binary on the shared filesystem, or /bin/sh). The working directory is the submitting
  // process's, and the environment is the submitting process's (sbatch's default --export=ALL).
  std::vector<std::string> argv;
  // Anything whose change must make a finished task run again though its argv did not change
  // (e.g. the hash of a config file the argv names). Part of the fingerprint.
  std::string key;
  // The ids of tasks of earlier groups whose outputs this task reads. When one of them runs
  // again, this task runs again after it. nullopt: every task of every earlier group.
  std::optional<std::vector<std::string>> after;
};

struct TaskGroup {
  std::string name;  // [a-z0-9_-]+, unique; part of the job name and the script's name
  std::vector<Task> tasks;
  bool reconstruct_resources = false;  // use SlurmOptions::reconstruct instead of ::work
};

enum class TaskState { kDone, kFailed, kPending, kRunning };
const char* TaskStateName(TaskState state);  // "done", "failed", "pending", "running"

struct TaskOutcome {
  std::string id;
  TaskState state = TaskState::kPending;
  bool submitted = false;          // submitted by this call (false: done before, or followed)
  std::string job;                 // "<array job id>_<index>" of its latest submission; "" if none
  std::filesystem::path log_file;  // RUN/slurm/<job>_<index>.log; empty if never submitted
  int exit_code = -1;              // from its result file; -1 when it wrote none
  std::string node;                // where it ran, when known
  std::string slurm_state;  // the last state Slurm reported: PENDING, COMPLETED, CANCELLED, ...
  std::string message;      // failed: why, in words ("exit code 1", "cancelled", "timed out")
  std::string reason;       // pending: why, as squeue says ("Resources", "Dependency", ...)
};

struct GroupOutcome {
  std::string name;
  std::vector<std::string> submitted_jobs;  // array job ids submitted by this call
  std::vector<std::string> followed_jobs;   // array job ids of earlier calls still followed
  std::vector<TaskOutcome> tasks;           // in the group's order
};

struct RunOutcome {
  std::vector<GroupOutcome> groups;
  bool finished = false;  // every task done or failed (always true after a wait)
  size_t submitted = 0;   // tasks submitted by this call
  size_t Count(TaskState state) const;
  // Every array job id submitted by this call, then every followed one, in group order.
  std::vector<std::string> JobIds() const;
  // One line per failed task: "fold_02/reconstruct: exit code 1 on node n3 (job 812_2); log:
  // RUN/slurm/812_2.log".
  std::vector<std::string> FailureLines() const;
};

// Runs the groups as described at the top of this file and returns what became of each task.
// `progress` (may be empty) is called from the calling thread after the plan is made and
// whenever a count changes while waiting. Throws UsageError for invalid tasks (bad or duplicate
// id, empty argv, relative argv[0], `after` naming no earlier task) and options; Error naming
// the program and its message when sbatch refuses a submission or squeue keeps failing (what was
// submitted so far is recorded and keeps running); Interrupted (see SlurmOptions::interrupted).
// A progress callback for RunTaskGroups that logs "slurm: 3/10 tasks done, 0 failed, 2 running,
// 5 pending" (LogInfo) when tasks have ended since the last line or a minute passed, and warns
// when tasks wait for a person (held). Each call returns a callback with its own state.
std::function<void(const Progress&)> ProgressLogger();

RunOutcome RunTaskGroups(const std::filesystem::path& run_dir, const std::vector<TaskGroup>& groups,
                         const SlurmOptions& options,
                         const std::function<void(const Progress&)>& progress = {});

}  // namespace rephoto::cluster
