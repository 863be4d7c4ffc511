#include "rephoto/cluster/slurm.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <ctime>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <thread>

#include "rephoto/cluster/slurm_text.h"
#include "rephoto/cluster/subprocess.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/run/run_folder.h"

namespace rephoto::cluster {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

SlurmCommands SlurmCommands::FromEnvironment() {
  SlurmCommands commands;
  const auto from = [](const char* name, std::string& value) {
    const char* text = std::getenv(name);
    if (text != nullptr && *text != '\0') value = text;
  };
  from("REPHOTO_SBATCH", commands.sbatch);
  from("REPHOTO_SQUEUE", commands.squeue);
  from("REPHOTO_SCANCEL", commands.scancel);
  from("REPHOTO_SACCT", commands.sacct);
  from("REPHOTO_SCONTROL", commands.scontrol);
  return commands;
}

void SlurmOptions::Check() const {
  REPHOTO_CHECK_USAGE(poll_seconds > 0 && poll_seconds <= 3600,
                      "--slurm-poll: {} s is not in (0, 3600]", poll_seconds);
  REPHOTO_CHECK_USAGE(result_grace_seconds >= 0, "slurm result grace: {} s is negative",
                      result_grace_seconds);
  REPHOTO_CHECK_USAGE(max_running >= 0, "--slurm-max-running: {} is negative", max_running);
  REPHOTO_CHECK_USAGE(max_array_size >= 0, "slurm max array size: {} is negative", max_array_size);
  for (const auto* resources : {&work, &reconstruct}) {
    REPHOTO_CHECK_USAGE(resources->cpus_per_task >= 0, "--slurm-cpus-per-task: {} is negative",
                        resources->cpus_per_task);
    for (const std::string& option : resources->options) {
      REPHOTO_CHECK_USAGE(option.rfind("-", 0) == 0,
                          "--slurm-option '{}': not an sbatch option (it must start with -)",
                          option);
      for (const char* ours : {"--array", "-a", "--output", "-o", "--error", "-e", "--parsable",
                               "--dependency", "-d", "--job-name", "-J", "--wrap"}) {
        const std::string_view name = std::string_view(option).substr(0, option.find('='));
        REPHOTO_CHECK_USAGE(name != ours,
                            "--slurm-option '{}': rephoto sets {} itself (see docs/cluster.md)",
                            option, ours);
      }
    }
  }
  for (const std::string* program : {&commands.sbatch, &commands.squeue, &commands.scancel,
                                     &commands.sacct, &commands.scontrol}) {
    REPHOTO_CHECK_USAGE(!program->empty(), "a Slurm program name is empty");
  }
}

const char* TaskStateName(TaskState state) {
  switch (state) {
    case TaskState::kDone:
      return "done";
    case TaskState::kFailed:
      return "failed";
    case TaskState::kPending:
      return "pending";
    case TaskState::kRunning:
      return "running";
  }
  return "?";
}

size_t RunOutcome::Count(TaskState state) const {
  size_t count = 0;
  for (const GroupOutcome& group : groups) {
    for (const TaskOutcome& task : group.tasks) count += task.state == state ? 1 : 0;
  }
  return count;
}

std::vector<std::string> RunOutcome::JobIds() const {
  std::vector<std::string> ids;
  for (const GroupOutcome& group : groups) {
    ids.insert(ids.end(), group.submitted_jobs.begin(), group.submitted_jobs.end());
  }
  for (const GroupOutcome& group : groups) {
    for (const std::string& job : group.followed_jobs) {
      if (std::find(ids.begin(), ids.end(), job) == ids.end()) ids.push_back(job);
    }
  }
  return ids;
}

std::vector<std::string> RunOutcome::FailureLines() const {
  std::vector<std::string> lines;
  for (const GroupOutcome& group : groups) {
    for (const TaskOutcome& task : group.tasks) {
      if (task.state != TaskState::kFailed) continue;
      std::string line = fmt::format("{}: {}", task.id, task.message);
      if (!task.job.empty()) line += fmt::format(" (job {})", task.job);
      if (!task.log_file.empty()) line += fmt::format("; log: {}", task.log_file.string());
      lines.push_back(std::move(line));
    }
  }
  return lines;
}

namespace {

// RunProgram, with a hint when a Slurm program cannot be started at all.
ProgramOutput RunSlurm(const std::vector<std::string>& argv) {
  try {
    return RunProgram(argv);
  } catch (const Error& e) {
    ThrowError(
        "{} (is Slurm installed here? REPHOTO_SBATCH, REPHOTO_SQUEUE, ... name other "
        "programs)",
        e.what());
  }
}

// ------------------------------------------------------------------------------ jobs.json

struct Submission {
  int sequence = 0;
  std::string job;  // array job id
  std::string group;
  std::string script;  // file name in RUN/slurm
  std::string submitted;
  std::vector<std::string> sbatch;
  std::vector<std::pair<std::string, std::string>> tasks;  // (id, fingerprint) by array index
};

std::string UtcNow() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

std::vector<Submission> ReadJobsFile(const fs::path& path) {
  std::vector<Submission> submissions;
  if (!fs::exists(path)) return submissions;
  const nlohmann::json doc =
      nlohmann::json::parse(ReadFileToString(path), nullptr, /*allow_exceptions=*/false);
  REPHOTO_CHECK(doc.is_object() && doc.value("schema", "") == "rephoto.cluster.jobs/1" &&
                    doc.contains("submissions") && doc["submissions"].is_array(),
                "{}: not a rephoto jobs file (rephoto.cluster.jobs/1)", path.string());
  try {
    for (const nlohmann::json& entry : doc["submissions"]) {
      Submission submission;
      submission.sequence = entry.at("sequence").get<int>();
      submission.job = entry.at("job").get<std::string>();
      submission.group = entry.at("group").get<std::string>();
      submission.script = entry.value("script", "");
      submission.submitted = entry.value("submitted", "");
      submission.sbatch = entry.value("sbatch", std::vector<std::string>{});
      for (const nlohmann::json& task : entry.at("tasks")) {
        submission.tasks.emplace_back(task.at("id").get<std::string>(),
                                      task.at("fingerprint").get<std::string>());
      }
      submissions.push_back(std::move(submission));
    }
  } catch (const nlohmann::json::exception& e) {
    ThrowError("{}: malformed submission record: {}", path.string(), e.what());
  }
  return submissions;
}

void WriteJobsFile(const fs::path& path, const std::vector<Submission>& submissions) {
  nlohmann::json list = nlohmann::json::array();
  for (const Submission& submission : submissions) {
    nlohmann::json tasks = nlohmann::json::array();
    for (size_t i = 0; i < submission.tasks.size(); ++i) {
      tasks.push_back({{"index", i},
                       {"id", submission.tasks[i].first},
                       {"fingerprint", submission.tasks[i].second}});
    }
    list.push_back({{"sequence", submission.sequence},
                    {"job", submission.job},
                    {"group", submission.group},
                    {"script", submission.script},
                    {"submitted", submission.submitted},
                    {"sbatch", submission.sbatch},
                    {"tasks", tasks}});
  }
  const nlohmann::json doc = {{"schema", "rephoto.cluster.jobs/1"}, {"submissions", list}};
  WriteTextFileAtomically(path, doc.dump(1) + "\n");
}

// ------------------------------------------------------------------------------ the runner

// A task's latest submission.
struct Placement {
  int submission = 0;  // 0: never submitted
  std::string job;     // array job id
  int index = -1;
  std::string fingerprint;
  std::string JobTask() const { return fmt::format("{}_{}", job, index); }
};

struct Tracked {
  const Task* task = nullptr;
  size_t group = 0;
  std::string fingerprint;
  std::vector<size_t> after;  // indices into Runner::tasks_
  std::optional<TaskResult> result;
  Placement placement;
  bool submit = false;                          // (re)submitted by this call
  bool final = false;                           // done or failed: nothing more to follow
  std::optional<Clock::time_point> gone_since;  // left the queue without a result
  TaskOutcome outcome;
};

class Runner {
 public:
  Runner(const fs::path& run_dir, const std::vector<TaskGroup>& groups, const SlurmOptions& options,
         const std::function<void(const Progress&)>& progress)
      : slurm_dir_(fs::absolute(run_dir).lexically_normal() / "slurm"),
        groups_(groups),
        options_(options),
        progress_(progress) {}

  RunOutcome Run();

 private:
  void IndexTasks();
  void LoadState();
  void RecoverJobIds();
  std::map<std::string, QueueEntry> QueryQueue(const std::set<std::string>& jobs, bool tolerate);
  void Plan();
  void Submit();
  std::string SubmitArray(size_t group, const std::vector<size_t>& tasks,
                          const std::vector<std::string>& after_jobs);
  void Follow();
  bool UpdateFromResult(Tracked& tracked);
  void UpdateFromQueue(Tracked& tracked, const QueueEntry* entry, Clock::time_point now);
  void ExplainVanished(std::vector<Tracked*>& vanished);
  void Report();
  RunOutcome Outcome() const;
  std::set<std::string> ActiveJobs(size_t before_group) const;
  void SetFinal(Tracked& tracked, TaskState state, std::string message);
  [[noreturn]] void ThrowInterrupted() const;

  fs::path slurm_dir_;
  const std::vector<TaskGroup>& groups_;
  const SlurmOptions& options_;
  const std::function<void(const Progress&)>& progress_;
  std::vector<Tracked> tasks_;
  std::map<std::string, size_t> by_id_;
  std::vector<Submission> submissions_;
  int next_submission_ = 1;
  int max_array_size_ = 0;
  bool sacct_works_ = true;
  std::vector<std::vector<std::string>> submitted_jobs_;  // per group
  std::vector<std::vector<std::string>> followed_jobs_;   // per group
  std::optional<Progress> last_progress_;
};

void Runner::IndexTasks() {
  std::set<std::string> names;
  for (size_t g = 0; g < groups_.size(); ++g) {
    const TaskGroup& group = groups_[g];
    CheckGroupName(group.name);
    REPHOTO_CHECK_USAGE(names.insert(group.name).second, "task group '{}': listed twice",
                        group.name);
    const size_t group_begin = tasks_.size();
    for (const Task& task : group.tasks) {
      CheckTaskId(task.id);
      REPHOTO_CHECK_USAGE(!task.argv.empty() && !task.argv[0].empty(), "task '{}': empty argv",
                          task.id);
      REPHOTO_CHECK_USAGE(fs::path(task.argv[0]).is_absolute(),
                          "task '{}': the program '{}' is not an absolute path (nodes must find "
                          "the same file)",
                          task.id, task.argv[0]);
      REPHOTO_CHECK_USAGE(by_id_.emplace(task.id, tasks_.size()).second,
                          "task '{}': the id is used twice", task.id);
      Tracked tracked;
      tracked.task = &task;
      tracked.group = g;
      tracked.fingerprint = TaskFingerprint(task);
      tracked.outcome.id = task.id;
      if (task.after) {
        for (const std::string& id : *task.after) {
          const auto found = by_id_.find(id);
          REPHOTO_CHECK_USAGE(found != by_id_.end() && found->second < group_begin,
                              "task '{}': 'after' names '{}', which is no task of an earlier group",
                              task.id, id);
          tracked.after.push_back(found->second);
        }
      } else {
        for (size_t i = 0; i < group_begin; ++i) tracked.after.push_back(i);
      }
      tasks_.push_back(std::move(tracked));
    }
  }
}

// Submissions recorded without a job id (the submitter died while sbatch ran): the job is the
// one whose batch script is the submission's; a submission Slurm does not know never happened.
void Runner::RecoverJobIds() {
  bool changed = false;
  for (auto it = submissions_.begin(); it != submissions_.end();) {
    if (!it->job.empty()) {
      ++it;
      continue;
    }
    const ProgramOutput output = RunSlurm({options_.commands.squeue, "-h", "-t", "all", "--name",
                                           options_.job_name + "-" + it->group, "-o", "%F|%o"});
    REPHOTO_CHECK(output.ok(), "squeue: {} (is Slurm reachable? SLURM_CONF, REPHOTO_SQUEUE)",
                  output.FirstLine());
    const std::optional<std::string> job =
        FindJobOfScript(output.out, (slurm_dir_ / it->script).string());
    changed = true;
    if (job) {
      it->job = *job;
      ++it;
    } else {
      it = submissions_.erase(it);
    }
  }
  if (changed) WriteJobsFile(slurm_dir_ / "jobs.json", submissions_);
}

void Runner::LoadState() {
  submissions_ = ReadJobsFile(slurm_dir_ / "jobs.json");
  RecoverJobIds();
  for (const Submission& submission : submissions_) {
    next_submission_ = std::max(next_submission_, submission.sequence + 1);
    for (size_t i = 0; i < submission.tasks.size(); ++i) {
      const auto found = by_id_.find(submission.tasks[i].first);
      if (found == by_id_.end()) continue;
      Placement& placement = tasks_[found->second].placement;
      if (submission.sequence >= placement.submission) {
        placement = {submission.sequence, submission.job, static_cast<int>(i),
                     submission.tasks[i].second};
      }
    }
  }
  for (Tracked& tracked : tasks_) {
    const fs::path path = ResultPath(slurm_dir_, tracked.task->id);
    std::error_code ec;
    if (!fs::exists(path, ec)) continue;
    std::optional<TaskResult> result;
    try {
      result = ParseTaskResult(ReadFileToString(path));
    } catch (const Error&) {
    }
    if (result && result->id == tracked.task->id) {
      tracked.result = result;
      next_submission_ = std::max(next_submission_, result->submission + 1);
    }
  }
}

std::map<std::string, QueueEntry> Runner::QueryQueue(const std::set<std::string>& jobs,
                                                     bool tolerate) {
  std::map<std::string, QueueEntry> entries;
  if (jobs.empty()) return entries;
  std::string list;
  for (const std::string& job : jobs) list += (list.empty() ? "" : ",") + job;
  const ProgramOutput output = RunSlurm(
      {options_.commands.squeue, "-h", "-r", "-t", "all", "-j", list, "-o", "%F|%K|%T|%r|%N"});
  if (!output.ok()) {
    // squeue refuses a list of job ids that are all unknown (purged after MinJobAge).
    if (output.err.find("Invalid job id") != std::string::npos) return entries;
    if (tolerate) throw Error(fmt::format("squeue: {}", output.FirstLine()));
    ThrowError("squeue: {} (is Slurm reachable? SLURM_CONF, REPHOTO_SQUEUE)", output.FirstLine());
  }
  for (QueueEntry& entry : ParseSqueue(output.out)) {
    entries[fmt::format("{}_{}", entry.array_job, entry.index)] = std::move(entry);
  }
  return entries;
}

std::set<std::string> Runner::ActiveJobs(size_t before_group) const {
  std::set<std::string> jobs;
  for (const Tracked& tracked : tasks_) {
    if (tracked.group < before_group && !tracked.final && !tracked.placement.job.empty()) {
      jobs.insert(tracked.placement.job);
    }
  }
  return jobs;
}

void Runner::SetFinal(Tracked& tracked, TaskState state, std::string message) {
  tracked.final = true;
  tracked.outcome.state = state;
  tracked.outcome.message = std::move(message);
}

// Decides, group by group, which tasks are done, which are followed and which are submitted.
void Runner::Plan() {
  std::set<std::string> recorded;
  for (const Tracked& tracked : tasks_) {
    const bool has_own_result =
        tracked.result && tracked.result->submission >= tracked.placement.submission;
    if (tracked.placement.submission > 0 && !has_own_result) {
      recorded.insert(tracked.placement.job);
    }
  }
  std::map<std::string, QueueEntry> queue = QueryQueue(recorded, false);
  // A task that is COMPLETING (ending, or being cancelled) will not run again: wait until Slurm
  // says how it ended, so that a task cancelled just before this call is submitted again now.
  const auto completing = [&] {
    for (const auto& [job_task, entry] : queue) {
      if (entry.state == "COMPLETING") return true;
    }
    return false;
  };
  for (const auto give_up = Clock::now() + std::chrono::seconds(60);
       completing() && Clock::now() < give_up;) {
    std::this_thread::sleep_for(std::chrono::milliseconds(250));
    queue = QueryQueue(recorded, false);
  }
  std::vector<std::string> cancel;
  for (Tracked& tracked : tasks_) {
    const std::optional<TaskResult>& result = tracked.result;
    bool done = options_.skip_succeeded && result && result->exit_code == 0 &&
                result->fingerprint == tracked.fingerprint &&
                result->submission >= tracked.placement.submission;
    bool input_submitted = false;
    for (size_t input : tracked.after) {
      const Tracked& before = tasks_[input];
      input_submitted = input_submitted || before.submit;
      const bool input_ok = before.final && before.outcome.state == TaskState::kDone && result &&
                            before.result->submission < result->submission;
      done = done && input_ok;
    }
    if (done) {
      SetFinal(tracked, TaskState::kDone, "");
      tracked.outcome.exit_code = 0;
      tracked.outcome.node = result->node;
      tracked.outcome.job = fmt::format("{}_{}", result->job, result->index);
      tracked.outcome.log_file = slurm_dir_ / (tracked.outcome.job + ".log");
      continue;
    }
    const Placement& placement = tracked.placement;
    const auto entry = placement.submission > 0 ? queue.find(placement.JobTask()) : queue.end();
    const bool active = entry != queue.end() && IsActiveState(entry->second.state);
    if (active && !input_submitted && placement.fingerprint == tracked.fingerprint) {
      tracked.outcome.state =
          entry->second.state == "PENDING" ? TaskState::kPending : TaskState::kRunning;
      tracked.outcome.slurm_state = entry->second.state;
      tracked.outcome.reason = entry->second.state == "PENDING" ? entry->second.reason : "";
      tracked.outcome.node = entry->second.node;
      tracked.outcome.job = placement.JobTask();
      tracked.outcome.log_file = slurm_dir_ / (placement.JobTask() + ".log");
      auto& followed = followed_jobs_[tracked.group];
      if (std::find(followed.begin(), followed.end(), placement.job) == followed.end()) {
        followed.push_back(placement.job);
      }
      continue;
    }
    // A stale copy (its input runs again, or its command changed) must not race the new one.
    if (active) cancel.push_back(placement.JobTask());
    tracked.submit = true;
  }
  if (!cancel.empty()) {
    std::vector<std::string> argv = {options_.commands.scancel};
    argv.insert(argv.end(), cancel.begin(), cancel.end());
    const ProgramOutput output = RunSlurm(argv);
    REPHOTO_CHECK(output.ok(), "scancel: {}", output.FirstLine());
  }
}

std::string Runner::SubmitArray(size_t group, const std::vector<size_t>& tasks,
                                const std::vector<std::string>& after_jobs) {
  const TaskGroup& task_group = groups_[group];
  ArraySpec spec;
  spec.submission = next_submission_++;
  spec.group = task_group.name;
  spec.slurm_dir = slurm_dir_;
  for (size_t index : tasks) spec.tasks.push_back(tasks_[index].task);
  spec.resources = task_group.reconstruct_resources ? &options_.reconstruct : &options_.work;
  spec.job_name = options_.job_name + "-" + task_group.name;
  spec.max_running = options_.max_running;
  spec.after_jobs = after_jobs;
  const std::string script_name = fmt::format("submit-{:04}-{}.sh", spec.submission, spec.group);
  const fs::path script = slurm_dir_ / script_name;
  std::vector<std::string> argv = {options_.commands.sbatch};
  const std::vector<std::string> arguments = SbatchArguments(spec, script);
  argv.insert(argv.end(), arguments.begin(), arguments.end());
  WriteTextFileAtomically(script, MakeArrayScript(spec, argv));
  for (const Task* task : spec.tasks) {  // the batch script only creates them when missing
    std::error_code ec;
    fs::create_directories(ResultPath(slurm_dir_, task->id).parent_path(), ec);
    REPHOTO_CHECK(!ec, "{}: cannot create folder: {}",
                  ResultPath(slurm_dir_, task->id).parent_path().string(), ec.message());
  }
  fs::permissions(script, fs::perms::owner_exec | fs::perms::group_exec, fs::perm_options::add);

  // Recorded before sbatch runs, without a job id: when this process dies before it learns
  // the id, the next call finds the job by its script (RecoverJobIds) instead of submitting the
  // tasks twice.
  Submission record;
  record.sequence = spec.submission;
  record.group = task_group.name;
  record.script = script_name;
  record.submitted = UtcNow();
  record.sbatch = argv;
  for (size_t index : tasks)
    record.tasks.emplace_back(tasks_[index].task->id, tasks_[index].fingerprint);
  submissions_.push_back(std::move(record));
  WriteJobsFile(slurm_dir_ / "jobs.json", submissions_);

  const ProgramOutput output = RunSlurm(argv);
  if (!output.ok()) {
    submissions_.pop_back();
    WriteJobsFile(slurm_dir_ / "jobs.json", submissions_);
    ThrowError("sbatch refused the {} task(s) of group '{}': {}", tasks.size(), task_group.name,
               output.FirstLine());
  }
  const std::string job = ParseSbatchJobId(output.out);
  submissions_.back().job = job;
  WriteJobsFile(slurm_dir_ / "jobs.json", submissions_);
  for (size_t i = 0; i < tasks.size(); ++i) {
    Tracked& tracked = tasks_[tasks[i]];
    tracked.placement = {spec.submission, job, static_cast<int>(i), tracked.fingerprint};
    tracked.outcome.submitted = true;
    tracked.outcome.state = TaskState::kPending;
    tracked.outcome.slurm_state = "PENDING";
    tracked.outcome.job = tracked.placement.JobTask();
    tracked.outcome.log_file = slurm_dir_ / (tracked.outcome.job + ".log");
    tracked.outcome.exit_code = -1;
    tracked.outcome.node.clear();
  }
  return job;
}

void Runner::Submit() {
  bool any = false;
  for (const Tracked& tracked : tasks_) any = any || tracked.submit;
  if (!any) return;
  if (options_.max_array_size > 0) {
    max_array_size_ = options_.max_array_size;
  } else {
    max_array_size_ = 1001;  // Slurm's default
    try {
      const ProgramOutput output = RunSlurm({options_.commands.scontrol, "show", "config"});
      if (output.ok()) max_array_size_ = ParseMaxArraySize(output.out).value_or(max_array_size_);
    } catch (const Error&) {
      // No scontrol: keep the default.
    }
  }
  for (size_t g = 0; g < groups_.size(); ++g) {
    std::vector<size_t> pending;
    for (size_t i = 0; i < tasks_.size(); ++i) {
      if (tasks_[i].group == g && tasks_[i].submit) pending.push_back(i);
    }
    const std::set<std::string> before = ActiveJobs(g);
    const std::vector<std::string> after_jobs(before.begin(), before.end());
    for (size_t begin = 0; begin < pending.size(); begin += static_cast<size_t>(max_array_size_)) {
      const size_t end = std::min(pending.size(), begin + static_cast<size_t>(max_array_size_));
      const std::vector<size_t> chunk(pending.begin() + static_cast<ptrdiff_t>(begin),
                                      pending.begin() + static_cast<ptrdiff_t>(end));
      submitted_jobs_[g].push_back(SubmitArray(g, chunk, after_jobs));
    }
  }
}

bool Runner::UpdateFromResult(Tracked& tracked) {
  const fs::path path = ResultPath(slurm_dir_, tracked.task->id);
  std::error_code ec;
  if (!fs::exists(path, ec)) return false;
  std::optional<TaskResult> result;
  try {
    result = ParseTaskResult(ReadFileToString(path));
  } catch (const Error&) {
    return false;
  }
  if (!result || result->id != tracked.task->id ||
      result->submission != tracked.placement.submission) {
    return false;
  }
  tracked.result = result;
  tracked.outcome.exit_code = result->exit_code;
  tracked.outcome.node = result->node;
  if (result->exit_code == 0) {
    SetFinal(tracked, TaskState::kDone, "");
  } else {
    SetFinal(tracked, TaskState::kFailed,
             fmt::format("exit code {} on node {}", result->exit_code, result->node));
  }
  return true;
}

void Runner::UpdateFromQueue(Tracked& tracked, const QueueEntry* entry, Clock::time_point now) {
  if (entry != nullptr) {
    tracked.outcome.slurm_state = entry->state;
    if (!entry->node.empty()) tracked.outcome.node = entry->node;
  }
  if (entry != nullptr && IsActiveState(entry->state)) {
    tracked.gone_since.reset();
    tracked.outcome.state = entry->state == "PENDING" ? TaskState::kPending : TaskState::kRunning;
    tracked.outcome.reason = entry->state == "PENDING" ? entry->reason : "";
    return;
  }
  // Left the queue (or finished) without a result file of this submission.
  if (!tracked.gone_since) tracked.gone_since = now;
  const bool wrote_nothing = entry != nullptr && entry->state != "COMPLETED" &&
                             entry->state != "FAILED";  // cancelled, timed out, node failed...
  const double waited = std::chrono::duration<double>(now - *tracked.gone_since).count();
  if (wrote_nothing && waited > 0) {
    SetFinal(tracked, TaskState::kFailed, DescribeFinalState(entry->state));
  } else if (waited >= options_.result_grace_seconds) {
    SetFinal(tracked, TaskState::kFailed,
             entry != nullptr
                 ? fmt::format("{} but wrote no result file {}", DescribeFinalState(entry->state),
                               ResultPath(slurm_dir_, tracked.task->id).string())
                 : "vanished: left the queue without a result file (node died?)");
  }
}

// Asks sacct (when the cluster keeps accounting) why tasks that left the queue failed.
void Runner::ExplainVanished(std::vector<Tracked*>& vanished) {
  if (vanished.empty() || !sacct_works_) return;
  std::set<std::string> jobs;
  for (const Tracked* tracked : vanished) jobs.insert(tracked->placement.job);
  std::string list;
  for (const std::string& job : jobs) list += (list.empty() ? "" : ",") + job;
  ProgramOutput output;
  try {
    output = RunSlurm({options_.commands.sacct, "-n", "-X", "-P", "-j", list, "-o",
                       "JobID,State,ExitCode,NodeList"});
  } catch (const Error&) {
    sacct_works_ = false;
    return;
  }
  if (!output.ok()) {
    sacct_works_ = false;  // "Slurm accounting storage is disabled"
    return;
  }
  std::map<std::string, QueueEntry> entries;
  for (QueueEntry& entry : ParseSacct(output.out)) {
    entries[fmt::format("{}_{}", entry.array_job, entry.index)] = std::move(entry);
  }
  for (Tracked* tracked : vanished) {
    const auto found = entries.find(tracked->placement.JobTask());
    if (found == entries.end()) continue;
    tracked->outcome.slurm_state = found->second.state;
    tracked->outcome.message =
        fmt::format("{} (sacct; no result file)", DescribeFinalState(found->second.state));
  }
}

void Runner::Report() {
  if (!progress_) return;
  Progress progress;
  progress.total = tasks_.size();
  for (const Tracked& tracked : tasks_) {
    switch (tracked.outcome.state) {
      case TaskState::kDone:
        ++progress.done;
        break;
      case TaskState::kFailed:
        ++progress.failed;
        break;
      case TaskState::kRunning:
        ++progress.running;
        break;
      case TaskState::kPending:
        ++progress.pending;
        progress.held += IsStuckReason(tracked.outcome.reason) ? 1 : 0;
        break;
    }
  }
  if (last_progress_ && last_progress_->done == progress.done &&
      last_progress_->failed == progress.failed && last_progress_->running == progress.running &&
      last_progress_->pending == progress.pending && last_progress_->held == progress.held) {
    return;
  }
  last_progress_ = progress;
  progress_(progress);
}

void Runner::Follow() {
  auto last_ok = Clock::now();
  for (;;) {
    std::set<std::string> jobs;
    for (const Tracked& tracked : tasks_) {
      if (!tracked.final) jobs.insert(tracked.placement.job);
    }
    if (jobs.empty()) break;
    const auto now = Clock::now();
    std::optional<std::map<std::string, QueueEntry>> queue;
    try {
      queue = QueryQueue(jobs, true);
      last_ok = now;
    } catch (const Error& e) {
      // slurmctld restarting or busy: collect what the result files say, and wait a while.
      const double failing = std::chrono::duration<double>(now - last_ok).count();
      if (failing > std::max(120.0, 10 * options_.poll_seconds)) {
        ThrowError(
            "{} for {:.0f} s; the jobs ({}) keep running: rerun the same command to follow "
            "them",
            e.what(), failing, fmt::join(jobs, ", "));
      }
    }
    std::vector<Tracked*> vanished;
    for (Tracked& tracked : tasks_) {
      if (tracked.final) continue;
      const QueueEntry* entry = nullptr;
      if (queue) {
        const auto found = queue->find(tracked.placement.JobTask());
        if (found != queue->end()) entry = &found->second;
        // A pending task has no result to read: no file system calls for the queue's tail.
        if (entry != nullptr && entry->state == "PENDING") {
          UpdateFromQueue(tracked, entry, now);
          continue;
        }
      }
      if (UpdateFromResult(tracked) || !queue) continue;
      UpdateFromQueue(tracked, entry, now);
      if (tracked.final && entry == nullptr) vanished.push_back(&tracked);
    }
    ExplainVanished(vanished);
    Report();
    bool all_final = true;
    for (const Tracked& tracked : tasks_) all_final = all_final && tracked.final;
    if (all_final) return;
    const auto wake = Clock::now() + std::chrono::duration_cast<Clock::duration>(
                                         std::chrono::duration<double>(options_.poll_seconds));
    while (Clock::now() < wake) {
      if (options_.interrupted && options_.interrupted()) ThrowInterrupted();
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  }
  Report();
}

void Runner::ThrowInterrupted() const {
  std::set<std::string> jobs;
  for (const Tracked& tracked : tasks_) {
    if (!tracked.final) jobs.insert(tracked.placement.job);
  }
  throw Interrupted(fmt::format(
      "interrupted: the Slurm jobs keep running ({}); rerun the same command to follow them and "
      "collect their results, or `scancel {}` to stop them",
      fmt::join(jobs, ", "), fmt::join(jobs, " ")));
}

RunOutcome Runner::Outcome() const {
  RunOutcome outcome;
  outcome.finished = true;
  for (size_t g = 0; g < groups_.size(); ++g) {
    GroupOutcome group;
    group.name = groups_[g].name;
    group.submitted_jobs = submitted_jobs_[g];
    group.followed_jobs = followed_jobs_[g];
    for (const Tracked& tracked : tasks_) {
      if (tracked.group != g) continue;
      group.tasks.push_back(tracked.outcome);
      outcome.finished = outcome.finished && tracked.final;
      outcome.submitted += tracked.outcome.submitted ? 1 : 0;
    }
    outcome.groups.push_back(std::move(group));
  }
  return outcome;
}

RunOutcome Runner::Run() {
  options_.Check();
  IndexTasks();
  submitted_jobs_.assign(groups_.size(), {});
  followed_jobs_.assign(groups_.size(), {});
  // RUN/slurm may already hold files of the caller (the task's config): any content is ours.
  const run::RunFolder lock =
      run::OpenRunFolder(slurm_dir_, "cluster", [](const fs::path&) { return true; });
  LoadState();
  Plan();
  Submit();
  Report();
  if (options_.wait) Follow();
  return Outcome();
}

}  // namespace

RunOutcome RunTaskGroups(const fs::path& run_dir, const std::vector<TaskGroup>& groups,
                         const SlurmOptions& options,
                         const std::function<void(const Progress&)>& progress) {
  Runner runner(run_dir, groups, options, progress);
  return runner.Run();
}

std::function<void(const Progress&)> ProgressLogger() {
  struct State {
    size_t finished = SIZE_MAX;  // done + failed at the last line
    size_t held = 0;
    std::chrono::steady_clock::time_point last_line{};
  };
  auto state = std::make_shared<State>();
  return [state](const Progress& p) {
    // A line when tasks end, else at most one a minute (a long queue wait stays readable).
    const auto now = std::chrono::steady_clock::now();
    if (p.held > 0 && p.held != state->held) {
      LogWarning(
          fmt::format("slurm: {} task(s) wait for a person, not for resources (held, or "
                      "an impossible dependency, account, QOS or constraint): see "
                      "`squeue --me -t PD -o '%i %r'`; `scontrol release JOB` runs held "
                      "ones",
                      p.held));
    }
    state->held = p.held;
    if (p.done + p.failed == state->finished && now - state->last_line < std::chrono::minutes(1)) {
      return;
    }
    state->finished = p.done + p.failed;
    state->last_line = now;
    LogInfo(fmt::format("slurm: {}/{} tasks done, {} failed, {} running, {} pending", p.done,
                        p.total, p.failed, p.running, p.pending));
  };
}

}  // namespace rephoto::cluster
