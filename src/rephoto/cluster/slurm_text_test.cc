// The text rephoto exchanges with Slurm, without Slurm: batch scripts are run by /bin/sh with
// the variables slurmstepd sets, and the parsers read output captured from Slurm 22.05.
#include "rephoto/cluster/slurm_text.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>

#include "rephoto/cluster/subprocess.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/testing/testing.h"

namespace rephoto::cluster {
namespace {

namespace fs = std::filesystem;
using testing::ErrorOf;

TEST(SlurmText, TaskIdsAreSafeRelativePaths) {
  for (const char* id : {"aggregate", "fold_02/reconstruct", "views/2/0-7", "a:b+c.d", "x.y/z"}) {
    EXPECT_NO_THROW(CheckTaskId(id)) << id;
  }
  EXPECT_EQ(ErrorOf([] { CheckTaskId("../x"); }),
            "task id '../x': empty, '.' or '..' path segment");
  for (const char* id : {"", "/abs", "a//b", "a/./b", "x/..", "a/", "."}) {
    EXPECT_THROW(CheckTaskId(id), UsageError) << id;
  }
  EXPECT_EQ(ErrorOf([] { CheckTaskId("a b"); }),
            "task id 'a b': character ' ' is not allowed (letters, digits and _ . : + - in "
            "segments joined by /)");
  EXPECT_THROW(CheckTaskId("a\nb"), UsageError);
  EXPECT_THROW(CheckTaskId("a\\b"), UsageError);
  EXPECT_THROW(CheckTaskId(std::string(201, 'a')), UsageError);
  EXPECT_NO_THROW(CheckGroupName("reconstruct"));
  EXPECT_NO_THROW(CheckGroupName("views_2-b"));
  EXPECT_THROW(CheckGroupName("Views"), UsageError);
  EXPECT_THROW(CheckGroupName("a/b"), UsageError);
  EXPECT_THROW(CheckGroupName(""), UsageError);
}

// The shell itself reads each word back as the original text.
TEST(SlurmText, ShellWordsReadBackUnchanged) {
  EXPECT_EQ(ShellQuote("it's"), "'it'\\''s'");
  const fs::path dir = testing::MakeTempDir();
  for (const std::string& value :
       {std::string("plain"), std::string("two words"), std::string("it's"),
        std::string("$HOME `id`"), std::string("line\nbreak"), std::string("back\\slash \"q\" ''"),
        std::string("")}) {
    const ProgramOutput output = RunProgram({"/bin/sh", "-c", "printf '%s' " + ShellQuote(value)});
    ASSERT_TRUE(output.ok()) << output.err;
    EXPECT_EQ(output.out, value);
  }
}

TEST(SlurmText, FingerprintSeparatesArgumentsAndKey) {
  const Task a{"t", {"/bin/echo", "a b"}, "", std::nullopt};
  const Task b{"t", {"/bin/echo", "a", "b"}, "", std::nullopt};
  const Task c{"t", {"/bin/echo", "a b"}, "config 1", std::nullopt};
  const Task d{"other id", {"/bin/echo", "a b"}, "", std::nullopt};
  EXPECT_EQ(TaskFingerprint(a).size(), 32u);
  EXPECT_EQ(TaskFingerprint(a).find_first_not_of("0123456789abcdef"), std::string::npos);
  EXPECT_NE(TaskFingerprint(a), TaskFingerprint(b));
  EXPECT_NE(TaskFingerprint(a), TaskFingerprint(c));
  EXPECT_EQ(TaskFingerprint(a), TaskFingerprint(d));  // the id is not the work
  EXPECT_EQ(TaskFingerprint(a), TaskFingerprint(Task{"t", {"/bin/echo", "a b"}, "", {}}));
}

TEST(SlurmText, SbatchArguments) {
  const Task one{"fold_00/reconstruct", {"/bin/true"}, "", std::nullopt};
  const Task two{"fold_01/reconstruct", {"/bin/true"}, "", std::nullopt};
  SlurmResources resources{.partition = "cpu",
                           .time = "2:00:00",
                           .mem = "8G",
                           .account = "lab",
                           .qos = "long",
                           .cpus_per_task = 4,
                           .options = {"--constraint=avx2", "--exclusive"}};
  ArraySpec spec{.submission = 3,
                 .group = "reconstruct",
                 .slurm_dir = "/runs/100%/slurm",
                 .tasks = {&one, &two},
                 .resources = &resources,
                 .job_name = "rephoto-reconstruct",
                 .max_running = 5,
                 .after_jobs = {"812", "813"}};
  EXPECT_EQ(SbatchArguments(spec, "/runs/100%/slurm/submit-0003-reconstruct.sh"),
            (std::vector<std::string>{
                "--parsable", "--job-name=rephoto-reconstruct", "--array=0-1%5",
                "--output=/runs/100%%/slurm/%A_%a.log", "--open-mode=append", "--partition=cpu",
                "--time=2:00:00", "--mem=8G", "--account=lab", "--qos=long", "--cpus-per-task=4",
                "--dependency=afterany:812:813", "--constraint=avx2", "--exclusive",
                "/runs/100%/slurm/submit-0003-reconstruct.sh"}));
  SlurmResources defaults;
  spec.resources = &defaults;
  spec.max_running = 0;
  spec.after_jobs.clear();
  spec.tasks = {&one};
  EXPECT_EQ(SbatchArguments(spec, "s.sh"),
            (std::vector<std::string>{"--parsable", "--job-name=rephoto-reconstruct", "--array=0-0",
                                      "--output=/runs/100%%/slurm/%A_%a.log", "--open-mode=append",
                                      "s.sh"}));
}

// Runs the array script as slurmstepd would, for one index.
ProgramOutput RunArrayTask(const fs::path& script, int index, const std::string& node = "n7") {
  return RunProgram({"/usr/bin/env", "SLURM_ARRAY_TASK_ID=" + std::to_string(index),
                     "SLURM_ARRAY_JOB_ID=812", "SLURMD_NODENAME=" + node, "/bin/sh",
                     script.string()});
}

TEST(SlurmText, ArrayScriptRunsTheIndexedTaskAndRecordsItsResult) {
  const fs::path dir = testing::MakeTempDir();
  const fs::path slurm_dir = dir / "slurm";
  const std::string out = (dir / "out it's.txt").string();
  const Task writer{"fold_00/views:0-3",
                    {"/bin/sh", "-c", "printf '%s' \"$1\" > \"$2\"", "sh", "a 'quoted' $arg", out},
                    "",
                    std::nullopt};
  const Task failing{"fold_01/views", {"/bin/sh", "-c", "echo failing; exit 3"}, "k", std::nullopt};
  const Task missing{"fold_02", {"/nonexistent/program"}, "", std::nullopt};
  SlurmResources resources;
  const ArraySpec spec{.submission = 4,
                       .group = "views",
                       .slurm_dir = slurm_dir,
                       .tasks = {&writer, &failing, &missing},
                       .resources = &resources,
                       .job_name = "rephoto-views"};
  const fs::path script = slurm_dir / "submit-0004-views.sh";
  WriteTextFileAtomically(script, MakeArrayScript(spec, {"sbatch", "--array=0-2", script}));

  ProgramOutput output = RunArrayTask(script, 0);
  EXPECT_EQ(output.exit_code, 0) << output.err;
  EXPECT_EQ(ReadFileToString(out), "a 'quoted' $arg");
  EXPECT_NE(output.out.find("# rephoto task fold_00/views:0-3: array job 812 index 0 on n7"),
            std::string::npos)
      << output.out;
  std::optional<TaskResult> result =
      ParseTaskResult(ReadFileToString(ResultPath(slurm_dir, writer.id)));
  ASSERT_TRUE(result);
  EXPECT_EQ(result->id, writer.id);
  EXPECT_EQ(result->fingerprint, TaskFingerprint(writer));
  EXPECT_EQ(result->submission, 4);
  EXPECT_EQ(result->job, "812");
  EXPECT_EQ(result->index, 0);
  EXPECT_EQ(result->node, "n7");
  EXPECT_EQ(result->exit_code, 0);
  EXPECT_EQ(result->start.size(), 20u);  // 2026-11-25T15:48:52Z
  EXPECT_GE(result->seconds, 0);

  output = RunArrayTask(script, 1, "a \"node\"");  // not a node name: not copied into JSON
  EXPECT_EQ(output.exit_code, 3);
  result = ParseTaskResult(ReadFileToString(ResultPath(slurm_dir, failing.id)));
  ASSERT_TRUE(result);
  EXPECT_EQ(result->exit_code, 3);
  EXPECT_EQ(result->node, "unknown");
  EXPECT_EQ(result->fingerprint, TaskFingerprint(failing));

  output = RunArrayTask(script, 2);
  EXPECT_EQ(output.exit_code, 127);
  result = ParseTaskResult(ReadFileToString(ResultPath(slurm_dir, missing.id)));
  ASSERT_TRUE(result);
  EXPECT_EQ(result->exit_code, 127);

  output = RunArrayTask(script, 3);
  EXPECT_EQ(output.exit_code, 2);
  EXPECT_NE(output.err.find("array index '3' is not a task of this script"), std::string::npos);
  // No temporary files are left behind.
  size_t files = 0;
  for (const auto& entry : fs::recursive_directory_iterator(slurm_dir / "results")) {
    files += entry.is_regular_file() ? 1 : 0;
    EXPECT_EQ(entry.path().string().find(".tmp-"), std::string::npos) << entry.path();
  }
  EXPECT_EQ(files, 3u);
}

TEST(SlurmText, ParsesSbatchOutput) {
  EXPECT_EQ(ParseSbatchJobId("812\n"), "812");
  EXPECT_EQ(ParseSbatchJobId("812;cluster2\n"), "812");
  EXPECT_EQ(ParseSbatchJobId("sbatch: warning: something\n913\n"), "913");
  EXPECT_EQ(ErrorOf([] { ParseSbatchJobId("Submitted batch job\n"); }),
            "sbatch: unexpected output 'Submitted batch job' (expected a job id)");
  EXPECT_THROW(ParseSbatchJobId(""), Error);
}

// Output of `squeue -h -r -t all -o '%F|%K|%T|%r|%N'` on the test cluster (Slurm 22.05.8).
TEST(SlurmText, ParsesSqueue) {
  const std::vector<QueueEntry> entries = ParseSqueue(
      "1|2|PENDING|Resources|\n"
      "1|0|RUNNING|None|rephoto-sc1-52287\n"
      "1|3|FAILED|NonZeroExitCode|rephoto-sc1-52287\n"
      "7|N/A|RUNNING|None|n1\n"
      "garbage\n"
      "\n"
      "8|1|CANCELLED|None|(null)\n");
  ASSERT_EQ(entries.size(), 4u);
  EXPECT_EQ(entries[0].array_job, "1");
  EXPECT_EQ(entries[0].index, 2);
  EXPECT_EQ(entries[0].state, "PENDING");
  EXPECT_EQ(entries[0].reason, "Resources");
  EXPECT_EQ(entries[0].node, "");
  EXPECT_EQ(entries[1].node, "rephoto-sc1-52287");
  EXPECT_EQ(entries[2].state, "FAILED");
  EXPECT_EQ(entries[3].array_job, "8");
  EXPECT_EQ(entries[3].node, "");
}

// Output of `sacct -n -X -P -o JobID,State,ExitCode,NodeList` (format of Slurm 22.05).
TEST(SlurmText, ParsesSacct) {
  const std::vector<QueueEntry> entries = ParseSacct(
      "812_2|CANCELLED by 0|0:15|n1\n"
      "812_[3-5]|PENDING|0:0|None assigned\n"
      "812_4|TIMEOUT|0:0|n2\n"
      "813|COMPLETED|0:0|n1\n"
      "814_0|FAILED|3:0|n1\n"
      "815_1|PENDING|0:0|None assigned\n");
  ASSERT_EQ(entries.size(), 4u);
  EXPECT_EQ(entries[0].array_job, "812");
  EXPECT_EQ(entries[0].index, 2);
  EXPECT_EQ(entries[0].state, "CANCELLED");
  EXPECT_EQ(entries[0].signal, 15);
  EXPECT_EQ(entries[1].state, "TIMEOUT");
  EXPECT_EQ(entries[2].exit_code, 3);
  EXPECT_EQ(entries[3].node, "");
}

TEST(SlurmText, FindsTheJobOfAScript) {
  const std::string output =
      "812|/runs/a|b/slurm/submit-0001-views.sh\n"
      "813|/runs/a|b/slurm/submit-0002-views.sh\n";
  EXPECT_EQ(FindJobOfScript(output, "/runs/a|b/slurm/submit-0002-views.sh"), "813");
  EXPECT_EQ(FindJobOfScript(output, "/runs/a|b/slurm/submit-0003-views.sh"), std::nullopt);
  EXPECT_EQ(FindJobOfScript("", "x"), std::nullopt);
}

TEST(SlurmText, ParsesMaxArraySize) {
  EXPECT_EQ(ParseMaxArraySize("Configuration data as of 2026-11-25T15:48:52\n"
                              "MaxArraySize            = 1001\n"
                              "MaxJobCount             = 10000\n"),
            1001);
  EXPECT_EQ(ParseMaxArraySize("MaxArraySize = 40001"), 40001);
  EXPECT_EQ(ParseMaxArraySize("MaxJobCount = 10000\n"), std::nullopt);
  EXPECT_EQ(ParseMaxArraySize("MaxArraySize = none\n"), std::nullopt);
}

TEST(SlurmText, States) {
  for (const char* state : {"PENDING", "RUNNING", "COMPLETING", "REQUEUED", "SUSPENDED"}) {
    EXPECT_TRUE(IsActiveState(state)) << state;
  }
  for (const char* state : {"COMPLETED", "FAILED", "CANCELLED", "TIMEOUT", "NODE_FAIL", ""}) {
    EXPECT_FALSE(IsActiveState(state)) << state;
  }
  for (const char* reason : {"JobHeldUser", "JobHeldAdmin", "launch failed requeued held",
                             "DependencyNeverSatisfied", "BadConstraints", "InvalidQOS"}) {
    EXPECT_TRUE(IsStuckReason(reason)) << reason;
  }
  for (const char* reason : {"Resources", "Priority", "Dependency", "None",
                             "QOSMaxJobsPerUserLimit", "ReqNodeNotAvail, UnavailableNodes:n1"}) {
    EXPECT_FALSE(IsStuckReason(reason)) << reason;
  }
  EXPECT_EQ(DescribeFinalState("TIMEOUT"), "timed out (--time)");
  EXPECT_EQ(DescribeFinalState("OUT_OF_MEMORY"), "ran out of memory (--mem)");
  EXPECT_EQ(DescribeFinalState("SPECIAL_EXIT"), "special_exit");
}

TEST(SlurmText, ParsesResults) {
  const std::string good =
      R"({"schema":"rephoto.cluster.result/1","id":"a/b","fingerprint":"00ff","submission":2,)"
      R"("job":"812","index":5,"node":"n1","exit_code":1,"start":"2026-11-25T15:48:52Z",)"
      R"("end":"2026-11-25T15:48:55Z","seconds":3})";
  const std::optional<TaskResult> result = ParseTaskResult(good);
  ASSERT_TRUE(result);
  EXPECT_EQ(result->id, "a/b");
  EXPECT_EQ(result->submission, 2);
  EXPECT_EQ(result->index, 5);
  EXPECT_EQ(result->exit_code, 1);
  EXPECT_EQ(result->seconds, 3);
  EXPECT_FALSE(ParseTaskResult(good.substr(0, good.size() / 2)));  // cut short
  EXPECT_FALSE(ParseTaskResult(R"({"schema":"other","id":"a"})"));
  EXPECT_FALSE(ParseTaskResult(R"({"schema":"rephoto.cluster.result/1","id":"a"})"));
  EXPECT_FALSE(ParseTaskResult("[1,2]"));
}

}  // namespace
}  // namespace rephoto::cluster
