// `rephoto evaluate` and `rephoto sweep` with --executor slurm on a real single-node Slurm
// (issue 19; testing/slurm_cluster.h starts it, the test is skipped when not root): the tables
// equal the local executor's byte for byte, every piece of work ran as a Slurm job, and a run
// whose submitting process was killed and one of whose tasks was cancelled finishes on the next
// invocation by submitting only what is missing.
#include <fmt/format.h>
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>

#include "rephoto/core/file.h"
#include "rephoto/synth/demo_files.h"
#include "rephoto/testing/slurm_cluster.h"
#include "rephoto/testing/testing.h"

namespace rephoto {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

using Outcome = testing::ShellOutcome;

Outcome RunCli(const std::string& args) {
  return testing::RunShell(std::string(REPHOTO_CLI) + " " + args);
}

const synth::DemoSceneFiles& Scene() {
  static const synth::DemoSceneFiles files = [] {
    synth::DemoSceneOptions options;
    options.image_width = 160;
    options.image_height = 120;
    options.camera_count = 9;
    options.ground_cells = 40;
    options.object_bands = 24;
    return synth::WriteDemoSceneFiles(options, testing::MakeTempDir() / "demo scene", [](size_t i) {
      return synth::PhotoSettings{1.0 + 0.02 * static_cast<double>(i % 3), 0.01, 7 + i};
    });
  }();
  return files;
}

// A cross-validated evaluation of the demo scene: each fold "reconstructs" by copying the
// uncoloured mesh, which --colorize colours from the fold's training photos.
std::string EvaluateArgs(const fs::path& out) {
  const synth::DemoSceneFiles& s = Scene();
  return fmt::format(
      "evaluate --scene '{}' --image-root '{}' --scheme kfold:3 --reconstruct 'cp \"{}\" "
      "{{out}}/model.ply' --model model.ply --colorize --metrics 1-ncc,cb+cr,dssim --out '{}'",
      s.sparse.string(), s.images.string(), s.plain.string(), out.string());
}

void ExpectSameTables(const fs::path& local, const fs::path& slurm) {
  for (const char* file : {"per_image.csv", "per_fold.csv", "summary.json"}) {
    ASSERT_TRUE(fs::exists(slurm / file)) << slurm / file;
    EXPECT_EQ(ReadFileToString(local / file), ReadFileToString(slurm / file)) << file;
  }
}

size_t CountFiles(const fs::path& dir) {
  size_t count = 0;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
    count += it->is_regular_file() ? 1 : 0;
  }
  return count;
}

TEST(SlurmExecutor, EvaluateAndSweepEqualTheLocalRuns) {
  REPHOTO_REQUIRE_SLURM(cluster);
  const fs::path dir = testing::MakeTempDir();
  const Outcome local = RunCli("-q " + EvaluateArgs(dir / "local"));
  ASSERT_EQ(local.exit_code, 0) << local.err;
  const Outcome slurm =
      RunCli(EvaluateArgs(dir / "slurm") + " --executor slurm --views-per-task 2");
  ASSERT_EQ(slurm.exit_code, 0) << slurm.err;
  ExpectSameTables(dir / "local", dir / "slurm");
  // 3 fold tasks, 9 views in chunks of at most 2 per fold (3 views a fold: 2 chunks), 1
  // aggregation: every one ran as an array task and left its result file.
  EXPECT_EQ(CountFiles(dir / "slurm" / "slurm" / "results"), 3u + 6u + 1u);
  EXPECT_THAT(slurm.err, HasSubstr("submitted 10 task(s)"));
  // The submitting process rendered and compared nothing: the views' records were written by
  // the jobs (each job's log names its task).
  EXPECT_THAT(ReadFileToString(dir / "slurm" / "run.json"), HasSubstr("\"status\": \"ok\""));
  // Again: nothing left to do, nothing submitted, the same tables.
  const Outcome again =
      RunCli(EvaluateArgs(dir / "slurm") + " --executor slurm --views-per-task 2");
  ASSERT_EQ(again.exit_code, 0) << again.err;
  EXPECT_THAT(again.err, Not(HasSubstr("submitted")));
  ExpectSameTables(dir / "local", dir / "slurm");

  // A sweep over texture noise: the settings' tables and the sweep's own.
  const synth::DemoSceneFiles& s = Scene();
  const fs::path config = dir / "sweep.toml";
  std::ofstream(config) << fmt::format(
      "scene = '{}'\nimage_root = '{}'\nmodel = '{}'\nscheme = 'kfold:3'\n"
      "metrics = ['1-ncc', 'cb+cr']\n[sweep]\ntexture_noise = [0, 0.1]\n",
      s.sparse.string(), s.images.string(), s.truth.string());
  const Outcome sweep_local =
      RunCli(fmt::format("-q sweep '{}' --out '{}'", config.string(), (dir / "sw_local").string()));
  ASSERT_EQ(sweep_local.exit_code, 0) << sweep_local.err;
  const Outcome sweep_slurm = RunCli(fmt::format("-q sweep '{}' --out '{}' --executor slurm",
                                                 config.string(), (dir / "sw_slurm").string()));
  ASSERT_EQ(sweep_slurm.exit_code, 0) << sweep_slurm.err;
  for (const char* file :
       {"sweep.csv", "sweep_per_fold.csv", "settings/texture_noise-0/per_image.csv",
        "settings/texture_noise-0.1/per_image.csv"}) {
    EXPECT_EQ(ReadFileToString(dir / "sw_local" / file), ReadFileToString(dir / "sw_slurm" / file))
        << file;
  }
  EXPECT_TRUE(fs::exists(dir / "sw_slurm" / "report.html"));
}

// The job ids of RUN/slurm/jobs.json by group.
std::map<std::string, std::string> JobsByGroup(const fs::path& run) {
  const auto jobs = nlohmann::json::parse(ReadFileToString(run / "slurm" / "jobs.json"));
  std::map<std::string, std::string> by_group;
  for (const auto& submission : jobs.at("submissions")) {
    by_group[submission.at("group").get<std::string>()] = submission.at("job").get<std::string>();
  }
  return by_group;
}

TEST(SlurmExecutor, KilledSubmitterAndCancelledTaskResumeWithOnlyTheMissingWork) {
  REPHOTO_REQUIRE_SLURM(cluster);
  const fs::path dir = testing::MakeTempDir();
  const Outcome local = RunCli("-q " + EvaluateArgs(dir / "local"));
  ASSERT_EQ(local.exit_code, 0) << local.err;
  const fs::path run = dir / "slurm";
  const std::string args = EvaluateArgs(run) + " --executor slurm --views-per-task 2";
  // The submitting process in the background, killed as soon as its jobs are queued.
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    const std::string command = std::string(REPHOTO_CLI) + " -q " + args + " >/dev/null 2>&1";
    execl("/bin/sh", "sh", "-c", ("exec " + command).c_str(), nullptr);
    _exit(127);
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  std::map<std::string, std::string> jobs;
  while (std::chrono::steady_clock::now() < deadline) {
    if (fs::exists(run / "slurm" / "jobs.json")) {
      jobs = JobsByGroup(run);
      if (jobs.count("aggregate")) break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  kill(pid, SIGKILL);
  waitpid(pid, nullptr, 0);
  ASSERT_TRUE(jobs.count("views")) << "no views array was submitted";
  // Cancel one view task (waiting for its fold task, or running).
  ASSERT_EQ(std::system(fmt::format("scancel {}_1", jobs["views"]).c_str()), 0);
  // Wait until the queue is empty, then resume.
  for (int i = 0; i < 600; ++i) {
    const std::string queue_file = (dir / "queue").string();
    std::system(fmt::format("squeue -h -o %i >'{}' 2>/dev/null", queue_file).c_str());
    if (ReadFileToString(queue_file).empty()) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  const Outcome resumed = RunCli(args);
  ASSERT_EQ(resumed.exit_code, 0) << resumed.err;
  // Only the cancelled view task, and the aggregation after it.
  EXPECT_THAT(resumed.err, HasSubstr("submitted 2 task(s)")) << resumed.err;
  ExpectSameTables(dir / "local", run);
}

}  // namespace
}  // namespace rephoto
