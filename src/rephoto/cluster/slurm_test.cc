// RunTaskGroups against a real single-node Slurm (testing/slurm_cluster.h): groups of small
// shell commands run as job arrays in order; failures are named with their logs; cancelled and
// killed tasks, and only they, are submitted again; --no-wait submits and a later call follows.
// sbatch calls are counted through a wrapper script (SlurmCommands::sbatch) that logs and
// forwards to the real sbatch.
#include "rephoto/cluster/slurm.h"

#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <fstream>
#include <nlohmann/json.hpp>
#include <thread>

#include "rephoto/cluster/slurm_text.h"
#include "rephoto/cluster/subprocess.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/testing/slurm_cluster.h"
#include "rephoto/testing/testing.h"

namespace rephoto::cluster {
namespace {

namespace fs = std::filesystem;

// Counts sbatch calls: a wrapper that appends its arguments to a log and runs sbatch.
class SbatchCounter {
 public:
  explicit SbatchCounter(const fs::path& dir) : script_(dir / "sbatch"), log_(dir / "sbatch.log") {
    WriteTextFileAtomically(script_, "#!/bin/sh\necho \"$*\" >> " + ShellQuote(log_.string()) +
                                         "\nexec sbatch \"$@\"\n");
    fs::permissions(script_, fs::perms::owner_all);
  }
  const fs::path& script() const { return script_; }
  size_t Count() const {
    if (!fs::exists(log_)) return 0;
    std::ifstream in(log_);
    size_t lines = 0;
    for (std::string line; std::getline(in, line);) ++lines;
    return lines;
  }

 private:
  fs::path script_, log_;
};

Task Sh(std::string id, std::string script,
        std::optional<std::vector<std::string>> after = std::nullopt) {
  return Task{std::move(id), {"/bin/sh", "-c", std::move(script)}, "", std::move(after)};
}

SlurmOptions TestOptions(const SbatchCounter& counter) {
  SlurmOptions options;
  options.commands.sbatch = counter.script().string();
  options.poll_seconds = 0.25;
  options.result_grace_seconds = 3;  // one machine: no NFS attribute cache to wait for
  options.work.time = "10";
  return options;
}

const TaskOutcome& Find(const RunOutcome& outcome, const std::string& id) {
  for (const GroupOutcome& group : outcome.groups) {
    for (const TaskOutcome& task : group.tasks) {
      if (task.id == id) return task;
    }
  }
  throw Error("no task " + id);
}

std::vector<nlohmann::json> Submissions(const fs::path& run) {
  return nlohmann::json::parse(ReadFileToString(run / "slurm/jobs.json"))["submissions"];
}

std::vector<std::string> SubmittedIds(const nlohmann::json& submission) {
  std::vector<std::string> ids;
  for (const auto& task : submission["tasks"]) ids.push_back(task["id"]);
  return ids;
}

// The squeue state of one array task ("" when squeue does not list it).
std::string QueueState(const std::string& job_task) {
  const ProgramOutput output =
      RunProgram({"squeue", "-h", "-r", "-t", "all", "-j", job_task.substr(0, job_task.find('_')),
                  "-o", "%F|%K|%T|%r|%N"});
  for (const QueueEntry& entry : ParseSqueue(output.out)) {
    if (fmt::format("{}_{}", entry.array_job, entry.index) == job_task) return entry.state;
  }
  return "";
}

bool WaitFor(const std::function<bool()>& condition, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    if (condition()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  return condition();
}

std::string Q(const fs::path& path) { return ShellQuote(path.string()); }

TEST(Slurm, GroupsRunAsArraysInOrderAndFinishedTasksAreNotSubmittedAgain) {
  REPHOTO_REQUIRE_SLURM(cluster);
  const fs::path dir = testing::MakeTempDir();
  const fs::path run = dir / "run folder's";  // paths reach sbatch and the script unharmed
  const fs::path out = dir / "out";
  fs::create_directories(out);
  SbatchCounter counter(dir);
  const SlurmOptions options = TestOptions(counter);
  // The caller may keep its own files in RUN/slurm (the tasks' config).
  WriteTextFileAtomically(run / "slurm/evaluate.json", "{}");

  // Each task writes a file; the later groups first check that every earlier file exists.
  std::vector<TaskGroup> groups(3);
  groups[0].name = "reconstruct";
  groups[0].reconstruct_resources = true;
  for (int i = 0; i < 3; ++i) {
    groups[0].tasks.push_back(Sh(fmt::format("fold_{:02}/reconstruct", i),
                                 fmt::format("echo fold {} > {}/r{}", i, Q(out), i)));
  }
  groups[1].name = "views";
  for (int i = 0; i < 2; ++i) {
    groups[1].tasks.push_back(
        Sh(fmt::format("views/{}", i),
           fmt::format("cd {} && cat r0 r1 r2 > v{} && echo views {}", Q(out), i, i)));
  }
  groups[2].name = "aggregate";
  groups[2].tasks.push_back(Sh("aggregate", fmt::format("cd {} && cat v0 v1 > all", Q(out))));

  std::vector<Progress> reports;
  const RunOutcome first =
      RunTaskGroups(run, groups, options, [&](const Progress& p) { reports.push_back(p); });
  EXPECT_TRUE(first.finished);
  EXPECT_EQ(first.Count(TaskState::kDone), 6u);
  EXPECT_EQ(first.submitted, 6u);
  EXPECT_TRUE(first.FailureLines().empty());
  EXPECT_EQ(counter.Count(), 3u);  // one array per group
  EXPECT_EQ(ReadFileToString(out / "all"), "fold 0\nfold 1\nfold 2\nfold 0\nfold 1\nfold 2\n");
  ASSERT_FALSE(reports.empty());
  EXPECT_EQ(reports.front().total, 6u);
  EXPECT_EQ(reports.front().pending + reports.front().running + reports.front().done, 6u);
  EXPECT_EQ(reports.back().done, 6u);

  // Records: three submissions, their tasks by array index, one log and result per task.
  const std::vector<nlohmann::json> submissions = Submissions(run);
  ASSERT_EQ(submissions.size(), 3u);
  EXPECT_EQ(submissions[0]["group"], "reconstruct");
  EXPECT_EQ(SubmittedIds(submissions[1]), (std::vector<std::string>{"views/0", "views/1"}));
  const std::string views_job = submissions[1]["job"];
  EXPECT_EQ(Find(first, "views/1").job, views_job + "_1");
  EXPECT_EQ(Find(first, "views/1").log_file, fs::absolute(run) / "slurm" / (views_job + "_1.log"));
  EXPECT_NE(ReadFileToString(Find(first, "views/1").log_file).find("views 1"), std::string::npos);
  EXPECT_EQ(Find(first, "views/1").node, cluster.node);
  const std::optional<TaskResult> result =
      ParseTaskResult(ReadFileToString(run / "slurm/results/fold_02/reconstruct.json"));
  ASSERT_TRUE(result);
  EXPECT_EQ(result->exit_code, 0);
  EXPECT_EQ(result->node, cluster.node);
  // Each array after the first depended on the previous one.
  EXPECT_EQ(
      submissions[1]["sbatch"].dump().find(
          "--dependency=afterany:" + submissions[0]["job"].get<std::string>()) != std::string::npos,
      true);
  // The views ran after every reconstruction (the files were there: exit 0 above), and the
  // same call again submits nothing.
  const RunOutcome again = RunTaskGroups(run, groups, options);
  EXPECT_TRUE(again.finished);
  EXPECT_EQ(again.Count(TaskState::kDone), 6u);
  EXPECT_EQ(again.submitted, 0u);
  EXPECT_EQ(counter.Count(), 3u);

  // A changed command (its fingerprint) runs again, and so do the tasks after it (their
  // `after` is every earlier task by default); the other reconstructions do not.
  groups[0].tasks[1].argv.back() += " # changed";
  const RunOutcome changed = RunTaskGroups(run, groups, options);
  EXPECT_TRUE(changed.finished);
  EXPECT_EQ(changed.Count(TaskState::kDone), 6u);
  EXPECT_EQ(changed.submitted, 4u);
  EXPECT_FALSE(Find(changed, "fold_00/reconstruct").submitted);
  EXPECT_TRUE(Find(changed, "fold_01/reconstruct").submitted);
  EXPECT_TRUE(Find(changed, "aggregate").submitted);
  EXPECT_EQ(counter.Count(), 6u);
}

TEST(Slurm, FailedTaskIsNamedWithItsLogAndOnlyItRunsAgain) {
  REPHOTO_REQUIRE_SLURM(cluster);
  const fs::path dir = testing::MakeTempDir();
  const fs::path run = dir / "run";
  SbatchCounter counter(dir);
  const SlurmOptions options = TestOptions(counter);
  const fs::path fixed = dir / "fixed";

  // fold 1 fails until `fixed` exists; each fold's views read only that fold's output.
  std::vector<TaskGroup> groups(3);
  groups[0].name = "reconstruct";
  groups[1].name = "views";
  for (int i = 0; i < 3; ++i) {
    const std::string out = (dir / fmt::format("r{}", i)).string();
    const std::string fail =
        i == 1 ? fmt::format("[ -e {} ] || {{ echo 'pipeline broke' >&2; exit 3; }}; ", Q(fixed))
               : "";
    groups[0].tasks.push_back(
        Sh(fmt::format("fold_{:02}/reconstruct", i), fail + "echo model > " + ShellQuote(out)));
    groups[1].tasks.push_back(
        Sh(fmt::format("fold_{:02}/views", i),
           "cat " + ShellQuote(out) + " >/dev/null 2>&1; echo views",
           std::vector<std::string>{fmt::format("fold_{:02}/reconstruct", i)}));
  }
  groups[2].name = "aggregate";
  groups[2].tasks.push_back(Sh("aggregate", "echo aggregate"));

  const RunOutcome first = RunTaskGroups(run, groups, options);
  EXPECT_TRUE(first.finished);
  EXPECT_EQ(first.Count(TaskState::kDone), 6u);  // afterany: the rest ran though fold 1 failed
  EXPECT_EQ(first.Count(TaskState::kFailed), 1u);
  const TaskOutcome& failed = Find(first, "fold_01/reconstruct");
  EXPECT_EQ(failed.exit_code, 3);
  const std::string job = Submissions(run)[0]["job"];
  const fs::path log = fs::absolute(run) / "slurm" / (job + "_1.log");
  ASSERT_EQ(first.FailureLines().size(), 1u);
  EXPECT_EQ(first.FailureLines()[0],
            fmt::format("fold_01/reconstruct: exit code 3 on node {} (job {}_1); log: {}",
                        cluster.node, job, log.string()));
  EXPECT_NE(ReadFileToString(log).find("pipeline broke"), std::string::npos);
  EXPECT_EQ(counter.Count(), 3u);

  // Fixed: the next call runs fold 1's reconstruction and its views again (they read it), and
  // the aggregation (after everything by default); nothing of folds 0 and 2.
  WriteTextFileAtomically(fixed, "");
  const RunOutcome second = RunTaskGroups(run, groups, options);
  EXPECT_TRUE(second.finished);
  EXPECT_EQ(second.Count(TaskState::kDone), 7u);
  EXPECT_EQ(second.submitted, 3u);
  const std::vector<nlohmann::json> submissions = Submissions(run);
  ASSERT_EQ(submissions.size(), 6u);
  EXPECT_EQ(SubmittedIds(submissions[3]), (std::vector<std::string>{"fold_01/reconstruct"}));
  EXPECT_EQ(SubmittedIds(submissions[4]), (std::vector<std::string>{"fold_01/views"}));
  EXPECT_EQ(SubmittedIds(submissions[5]), (std::vector<std::string>{"aggregate"}));
  EXPECT_EQ(counter.Count(), 6u);

  // A caller that keeps its own record of what is done (its outputs were deleted, say) passes
  // only what must run, and says so: a task that succeeded before is submitted all the same.
  SlurmOptions rerun = options;
  rerun.skip_succeeded = false;
  const std::vector<TaskGroup> only_fold_2 = {
      TaskGroup{"reconstruct", {groups[0].tasks[2]}, false}};
  const RunOutcome third = RunTaskGroups(run, only_fold_2, rerun);
  EXPECT_EQ(third.Count(TaskState::kDone), 1u);
  EXPECT_EQ(third.submitted, 1u);
  EXPECT_EQ(counter.Count(), 7u);
  EXPECT_EQ(RunTaskGroups(run, only_fold_2, options).submitted, 0u);  // the default reuses it
}

// The acceptance scenario, on shell tasks: submit without waiting, cancel one array
// task with scancel and kill another mid-run (as a node dying would), then the same call again
// submits only those two and the task after them, and finishes.
TEST(Slurm, CancelledAndKilledTasksAreSubmittedAgainAndOnlyThey) {
  REPHOTO_REQUIRE_SLURM(cluster);
  const fs::path dir = testing::MakeTempDir();
  const fs::path run = dir / "run";
  SbatchCounter counter(dir);
  SlurmOptions options = TestOptions(counter);
  const fs::path slow = dir / "slow";
  WriteTextFileAtomically(slow, "");

  // work/2 and work/3 sleep while `slow` exists; work/3 records its pid and its wrapper's.
  std::vector<TaskGroup> groups(2);
  groups[0].name = "work";
  groups[0].tasks = {
      Sh("work/0", "echo zero"), Sh("work/1", "echo one"),
      Sh("work/2", fmt::format("[ -e {} ] && exec sleep 300; echo two", Q(slow))),
      Sh("work/3", fmt::format("echo \"$PPID $$\" > {}; [ -e {} ] && exec sleep 300; echo three",
                               Q(dir / "pids"), Q(slow)))};
  groups[1].name = "aggregate";
  groups[1].tasks = {Sh("aggregate", "echo aggregate")};

  options.wait = false;
  const RunOutcome submitted = RunTaskGroups(run, groups, options);
  EXPECT_FALSE(submitted.finished);
  EXPECT_EQ(submitted.submitted, 5u);
  ASSERT_EQ(submitted.JobIds().size(), 2u);
  EXPECT_EQ(counter.Count(), 2u);
  const std::string job = submitted.JobIds()[0];

  // A second call without waiting follows what is queued: nothing new is submitted.
  const RunOutcome followed = RunTaskGroups(run, groups, options);
  EXPECT_EQ(followed.submitted, 0u);
  EXPECT_EQ(followed.groups[0].followed_jobs, std::vector<std::string>{job});
  EXPECT_EQ(counter.Count(), 2u);

  ASSERT_TRUE(
      WaitFor([&] { return QueueState(job + "_2") == "RUNNING" && fs::exists(dir / "pids"); }, 120))
      << "work/2: " << QueueState(job + "_2");
  ASSERT_EQ(RunProgram({"scancel", job + "_2"}).exit_code, 0);
  std::istringstream pids(ReadFileToString(dir / "pids"));
  pid_t wrapper = 0, task = 0;
  pids >> wrapper >> task;
  ASSERT_GT(wrapper, 1);
  ASSERT_GT(task, 1);
  ::kill(task, SIGKILL);
  ::kill(wrapper, SIGKILL);
  ASSERT_TRUE(WaitFor([&] { return QueueState(job + "_3") != "RUNNING"; }, 60));
  fs::remove(slow);

  options.wait = true;
  const RunOutcome finished = RunTaskGroups(run, groups, options);
  EXPECT_TRUE(finished.finished);
  EXPECT_EQ(finished.Count(TaskState::kDone), 5u)
      << fmt::format("{}", fmt::join(finished.FailureLines(), "\n"));
  EXPECT_EQ(finished.submitted, 3u);
  EXPECT_FALSE(Find(finished, "work/0").submitted);
  EXPECT_FALSE(Find(finished, "work/1").submitted);
  EXPECT_TRUE(Find(finished, "work/2").submitted);
  EXPECT_TRUE(Find(finished, "work/3").submitted);
  const std::vector<nlohmann::json> submissions = Submissions(run);
  ASSERT_EQ(submissions.size(), 4u);
  EXPECT_EQ(SubmittedIds(submissions[2]), (std::vector<std::string>{"work/2", "work/3"}));
  EXPECT_EQ(SubmittedIds(submissions[3]), (std::vector<std::string>{"aggregate"}));
  EXPECT_EQ(counter.Count(), 4u);
  EXPECT_NE(ReadFileToString(Find(finished, "work/3").log_file).find("three"), std::string::npos);
}

TEST(Slurm, InterruptedWaitLeavesTheJobsRunningAndTheNextCallFollowsThem) {
  REPHOTO_REQUIRE_SLURM(cluster);
  const fs::path dir = testing::MakeTempDir();
  const fs::path run = dir / "run";
  SbatchCounter counter(dir);
  SlurmOptions options = TestOptions(counter);
  std::vector<TaskGroup> groups(1);
  groups[0].name = "work";
  groups[0].tasks = {Sh("a", "sleep 2; echo a"), Sh("b", "sleep 2; echo b")};

  options.interrupted = [] { return true; };
  std::string message;
  try {
    RunTaskGroups(run, groups, options);
  } catch (const Interrupted& e) {
    message = e.what();
  }
  const std::string job = Submissions(run)[0]["job"];
  EXPECT_EQ(message, fmt::format("interrupted: the Slurm jobs keep running ({}); rerun the same "
                                 "command to follow them and collect their results, or `scancel "
                                 "{}` to stop them",
                                 job, job));
  options.interrupted = {};
  const RunOutcome outcome = RunTaskGroups(run, groups, options);
  EXPECT_TRUE(outcome.finished);
  EXPECT_EQ(outcome.Count(TaskState::kDone), 2u);
  EXPECT_EQ(outcome.submitted, 0u);
  EXPECT_EQ(counter.Count(), 1u);
}

// The submitter died after sbatch submitted an array but before it recorded the job id: the
// next call finds the job by its batch script and follows it instead of submitting again.
TEST(Slurm, SubmissionWithoutARecordedJobIdIsFoundByItsScript) {
  REPHOTO_REQUIRE_SLURM(cluster);
  const fs::path dir = testing::MakeTempDir();
  const fs::path run = dir / "run";
  SbatchCounter counter(dir);
  SlurmOptions options = TestOptions(counter);
  std::vector<TaskGroup> groups(1);
  groups[0].name = "work";
  groups[0].tasks = {Sh("a", "sleep 1; echo a"), Sh("b", "sleep 1; echo b")};
  options.wait = false;
  const std::string job = RunTaskGroups(run, groups, options).JobIds().at(0);
  nlohmann::json jobs = nlohmann::json::parse(ReadFileToString(run / "slurm/jobs.json"));
  jobs["submissions"][0]["job"] = "";
  WriteTextFileAtomically(run / "slurm/jobs.json", jobs.dump());

  options.wait = true;
  const RunOutcome outcome = RunTaskGroups(run, groups, options);
  EXPECT_EQ(outcome.Count(TaskState::kDone), 2u);
  EXPECT_EQ(outcome.submitted, 0u);
  EXPECT_EQ(counter.Count(), 1u);
  EXPECT_EQ(Submissions(run)[0]["job"], job);
  EXPECT_EQ(Find(outcome, "b").job, job + "_1");
}

TEST(Slurm, LargeGroupsAreSplitIntoArraysOfMaxArraySize) {
  REPHOTO_REQUIRE_SLURM(cluster);
  const fs::path dir = testing::MakeTempDir();
  const fs::path run = dir / "run";
  SbatchCounter counter(dir);
  SlurmOptions options = TestOptions(counter);
  options.max_array_size = 2;
  std::vector<TaskGroup> groups(2);
  groups[0].name = "views";
  for (int i = 0; i < 5; ++i) {
    groups[0].tasks.push_back(
        Sh(fmt::format("views/{}", i), fmt::format("echo {} > {}", i, Q(dir / std::to_string(i)))));
  }
  groups[1].name = "aggregate";
  groups[1].tasks = {Sh("aggregate", fmt::format("cd {} && cat 0 1 2 3 4 > all", Q(dir)))};
  const RunOutcome outcome = RunTaskGroups(run, groups, options);
  EXPECT_EQ(outcome.Count(TaskState::kDone), 6u);
  EXPECT_EQ(outcome.groups[0].submitted_jobs.size(), 3u);  // 2 + 2 + 1
  EXPECT_EQ(counter.Count(), 4u);
  EXPECT_EQ(ReadFileToString(dir / "all"), "0\n1\n2\n3\n4\n");
  // The aggregation depended on all three arrays.
  const std::vector<nlohmann::json> submissions = Submissions(run);
  const std::string dependency = fmt::format(
      "--dependency=afterany:{}:{}:{}", submissions[0]["job"].get<std::string>(),
      submissions[1]["job"].get<std::string>(), submissions[2]["job"].get<std::string>());
  EXPECT_NE(submissions[3]["sbatch"].dump().find(dependency), std::string::npos)
      << submissions[3]["sbatch"].dump();
}

// Resources reach Slurm: the controller reports the time limit, memory and CPUs asked for,
// and a verbatim option (--comment) as given.
TEST(Slurm, ResourcesAndOptionsReachSlurm) {
  REPHOTO_REQUIRE_SLURM(cluster);
  const fs::path dir = testing::MakeTempDir();
  SbatchCounter counter(dir);
  SlurmOptions options = TestOptions(counter);
  options.reconstruct = {
      .time = "7", .mem = "100M", .cpus_per_task = 2, .options = {"--comment=rephoto test"}};
  std::vector<TaskGroup> groups(1);
  groups[0].name = "reconstruct";
  groups[0].reconstruct_resources = true;
  groups[0].tasks = {Sh("fold_00/reconstruct", "echo \"cpus $SLURM_CPUS_PER_TASK\"")};
  const RunOutcome outcome = RunTaskGroups(dir / "run", groups, options);
  ASSERT_EQ(outcome.Count(TaskState::kDone), 1u);
  const std::string job = Find(outcome, "fold_00/reconstruct").job;
  const ProgramOutput shown = RunProgram({"scontrol", "show", "job", job});
  ASSERT_TRUE(shown.ok()) << shown.err;
  EXPECT_NE(shown.out.find("TimeLimit=00:07:00"), std::string::npos) << shown.out;
  EXPECT_NE(shown.out.find("MinMemoryNode=100M"), std::string::npos) << shown.out;
  EXPECT_NE(shown.out.find("CPUs/Task=2"), std::string::npos) << shown.out;
  EXPECT_NE(shown.out.find("Comment=rephoto test"), std::string::npos) << shown.out;
  EXPECT_NE(ReadFileToString(Find(outcome, "fold_00/reconstruct").log_file).find("cpus 2"),
            std::string::npos);
}

// Held tasks (here submitted with --hold) are counted as waiting for a person; once released
// they run and the call finishes.
TEST(Slurm, HeldTasksAreReportedAndRunWhenReleased) {
  REPHOTO_REQUIRE_SLURM(cluster);
  const fs::path dir = testing::MakeTempDir();
  const fs::path run = dir / "run";
  SbatchCounter counter(dir);
  SlurmOptions options = TestOptions(counter);
  options.work.options = {"--hold"};
  std::vector<TaskGroup> groups(1);
  groups[0].name = "work";
  groups[0].tasks = {Sh("a", "echo a"), Sh("b", "echo b")};
  size_t most_held = 0;
  const RunOutcome outcome = RunTaskGroups(run, groups, options, [&](const Progress& p) {
    if (p.held > 0 && most_held == 0) {
      const std::string job = Submissions(run)[0]["job"];
      EXPECT_EQ(RunProgram({"scontrol", "release", job}).exit_code, 0);
    }
    most_held = std::max(most_held, p.held);
  });
  EXPECT_EQ(most_held, 2u);
  EXPECT_EQ(outcome.Count(TaskState::kDone), 2u);
}

TEST(Slurm, BadTasksAndRefusedSubmissionsAreOneLineErrors) {
  REPHOTO_REQUIRE_SLURM(cluster);
  const fs::path dir = testing::MakeTempDir();
  SbatchCounter counter(dir);
  SlurmOptions options = TestOptions(counter);
  std::vector<TaskGroup> groups(1);
  groups[0].name = "work";
  groups[0].tasks = {Task{"a", {"sh", "-c", "true"}, "", std::nullopt}};
  EXPECT_EQ(testing::ErrorOf([&] { RunTaskGroups(dir / "run", groups, options); }),
            "task 'a': the program 'sh' is not an absolute path (nodes must find the same file)");
  groups[0].tasks = {Sh("a", "true"), Sh("a", "false")};
  EXPECT_EQ(testing::ErrorOf([&] { RunTaskGroups(dir / "run", groups, options); }),
            "task 'a': the id is used twice");
  groups[0].tasks = {Sh("a", "true", std::vector<std::string>{"b"})};
  EXPECT_EQ(testing::ErrorOf([&] { RunTaskGroups(dir / "run", groups, options); }),
            "task 'a': 'after' names 'b', which is no task of an earlier group");
  groups[0].tasks = {Sh("a", "true")};
  options.work.partition = "no_such_partition";
  const std::string refused =
      testing::ErrorOf([&] { RunTaskGroups(dir / "run", groups, options); });
  EXPECT_EQ(refused.rfind("sbatch refused the 1 task(s) of group 'work': sbatch: error: ", 0), 0u)
      << refused;
  EXPECT_NE(refused.find("partition"), std::string::npos) << refused;
  options.work.partition.clear();
  options.work.options = {"--array=0-3"};
  EXPECT_EQ(testing::ErrorOf([&] { RunTaskGroups(dir / "run", groups, options); }),
            "--slurm-option '--array=0-3': rephoto sets --array itself (see docs/cluster.md)");
}

// A task that leaves the queue without a result file (its node died; here its wrapper is
// killed and a squeue wrapper hides the job) fails as vanished, and sacct, where the cluster
// keeps accounting, says how it ended.
TEST(Slurm, TaskThatVanishesIsNamedAndSacctSaysWhy) {
  REPHOTO_REQUIRE_SLURM(cluster);
  const fs::path dir = testing::MakeTempDir();
  SbatchCounter counter(dir);
  SlurmOptions options = TestOptions(counter);
  options.commands.squeue = (dir / "squeue").string();
  WriteTextFileAtomically(options.commands.squeue, "#!/bin/sh\nsqueue \"$@\" >/dev/null\n");
  fs::permissions(options.commands.squeue, fs::perms::owner_all);
  std::vector<TaskGroup> groups(1);
  groups[0].name = "work";
  groups[0].tasks = {Sh("dies", "kill -9 $PPID")};

  RunOutcome outcome = RunTaskGroups(dir / "run", groups, options);
  ASSERT_EQ(outcome.Count(TaskState::kFailed), 1u);
  const std::string job = Find(outcome, "dies").job;
  EXPECT_EQ(outcome.FailureLines()[0],
            fmt::format("dies: vanished: left the queue without a result file (node died?) (job "
                        "{}); log: {}",
                        job, (fs::absolute(dir / "run") / "slurm" / (job + ".log")).string()));

  // The next call submits it again; this time sacct answers.
  options.commands.sacct = (dir / "sacct").string();
  WriteTextFileAtomically(options.commands.sacct,
                          "#!/bin/sh\necho \"${5}_0|NODE_FAIL|0:0|n1\"\n");  // $5: the job list
  fs::permissions(options.commands.sacct, fs::perms::owner_all);
  outcome = RunTaskGroups(dir / "run", groups, options);
  ASSERT_EQ(outcome.Count(TaskState::kFailed), 1u);
  EXPECT_TRUE(Find(outcome, "dies").submitted);
  EXPECT_EQ(Find(outcome, "dies").message, "its node failed (sacct; no result file)");
  EXPECT_EQ(Find(outcome, "dies").slurm_state, "NODE_FAIL");
  EXPECT_EQ(counter.Count(), 2u);
}

TEST(Slurm, MissingSlurmProgramIsNamed) {
  const fs::path dir = testing::MakeTempDir();
  SlurmOptions options;
  options.commands.sbatch = (dir / "no-sbatch").string();
  std::vector<TaskGroup> groups(1);
  groups[0].name = "work";
  groups[0].tasks = {Sh("a", "true")};
  EXPECT_EQ(testing::ErrorOf([&] { RunTaskGroups(dir / "run", groups, options); }),
            fmt::format("{}: cannot start: No such file or directory (is Slurm installed here? "
                        "REPHOTO_SBATCH, REPHOTO_SQUEUE, ... name other programs)",
                        options.commands.sbatch));
}

}  // namespace
}  // namespace rephoto::cluster
