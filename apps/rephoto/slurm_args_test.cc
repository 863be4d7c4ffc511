// --executor and --slurm-* options: what reaches cluster::SlurmOptions, and the one-line errors.
#include "slurm_args.h"

#include <gtest/gtest.h>

#include "rephoto/cluster/slurm_settings.h"
#include "rephoto/core/error.h"
#include "rephoto/testing/testing.h"

namespace rephoto::cli {
namespace {

struct Parsed {
  std::optional<cluster::SlurmOptions> options;
  std::string error;
};

Parsed Parse(std::vector<std::string> argv, cluster::SlurmOptions base = {}) {
  CLI::App app;
  ExecutorArguments args;
  AddExecutorOptions(app, &args);
  argv.insert(argv.begin(), "rephoto");
  std::vector<const char*> raw;
  for (const std::string& arg : argv) raw.push_back(arg.c_str());
  app.parse(static_cast<int>(raw.size()), raw.data());
  Parsed parsed;
  parsed.error = testing::ErrorOf([&] { parsed.options = MakeSlurmOptions(args, base); });
  return parsed;
}

TEST(SlurmArgs, LocalIsTheDefault) {
  const Parsed parsed = Parse({});
  EXPECT_EQ(parsed.error, "(no error)");
  EXPECT_FALSE(parsed.options);
  EXPECT_EQ(Parse({"--slurm-time", "10"}).error, "--slurm-time needs --executor slurm");
  EXPECT_EQ(Parse({"--no-wait"}).error, "--wait/--no-wait needs --executor slurm");
}

TEST(SlurmArgs, FlagsReachTheOptions) {
  const Parsed parsed = Parse({"--executor",
                               "slurm",
                               "--no-wait",
                               "--slurm-partition",
                               "cpu",
                               "--slurm-time",
                               "1:00:00",
                               "--slurm-mem",
                               "4G",
                               "--slurm-account",
                               "lab",
                               "--slurm-qos",
                               "normal",
                               "--slurm-cpus-per-task",
                               "2",
                               "--slurm-option=--constraint=avx2",
                               "--slurm-option",
                               "--exclusive",
                               "--slurm-reconstruct-time",
                               "1-00:00:00",
                               "--slurm-reconstruct-cpus-per-task",
                               "16",
                               "--slurm-reconstruct-option=--gres=gpu:1",
                               "--slurm-max-running",
                               "4",
                               "--slurm-poll",
                               "10"});
  ASSERT_EQ(parsed.error, "(no error)");
  ASSERT_TRUE(parsed.options);
  const cluster::SlurmOptions& o = *parsed.options;
  EXPECT_FALSE(o.wait);
  EXPECT_EQ(o.work.partition, "cpu");
  EXPECT_EQ(o.work.time, "1:00:00");
  EXPECT_EQ(o.work.mem, "4G");
  EXPECT_EQ(o.work.account, "lab");
  EXPECT_EQ(o.work.qos, "normal");
  EXPECT_EQ(o.work.cpus_per_task, 2);
  EXPECT_EQ(o.work.options, (std::vector<std::string>{"--constraint=avx2", "--exclusive"}));
  // Unset reconstruction resources take the work resources; options add up.
  EXPECT_EQ(o.reconstruct.partition, "cpu");
  EXPECT_EQ(o.reconstruct.time, "1-00:00:00");
  EXPECT_EQ(o.reconstruct.mem, "4G");
  EXPECT_EQ(o.reconstruct.account, "lab");
  EXPECT_EQ(o.reconstruct.cpus_per_task, 16);
  EXPECT_EQ(o.reconstruct.options,
            (std::vector<std::string>{"--constraint=avx2", "--exclusive", "--gres=gpu:1"}));
  EXPECT_EQ(o.max_running, 4);
  EXPECT_EQ(o.poll_seconds, 10);
}

TEST(SlurmArgs, FlagsOverrideTheConfigFile) {
  cluster::SlurmOptions base;
  cluster::SetSlurmSetting(base, "time", "30", "exp.toml: [slurm] time");
  cluster::SetSlurmSetting(base, "account", "lab", "exp.toml: [slurm] account");
  const Parsed parsed = Parse({"--executor", "slurm", "--slurm-time", "45"}, base);
  ASSERT_TRUE(parsed.options);
  EXPECT_EQ(parsed.options->work.time, "45");
  EXPECT_EQ(parsed.options->work.account, "lab");
  EXPECT_TRUE(parsed.options->wait);
}

TEST(SlurmArgs, ConfigTable) {
  cluster::SlurmOptions options;
  cluster::ApplySlurmTable(options, nlohmann::json::parse(R"({
      "partition": "cpu", "time": "0:30:00", "cpus_per_task": 4, "mem": "8G",
      "option": ["--constraint=avx2", "--exclusive"], "reconstruct-time": 360,
      "reconstruct_option": "--gres=gpu:1", "max-running": 10, "poll": 7.5})"),
                           "exp.toml");
  EXPECT_EQ(options.work.partition, "cpu");
  EXPECT_EQ(options.work.time, "0:30:00");
  EXPECT_EQ(options.work.cpus_per_task, 4);
  EXPECT_EQ(options.work.mem, "8G");
  EXPECT_EQ(options.work.options, (std::vector<std::string>{"--constraint=avx2", "--exclusive"}));
  EXPECT_EQ(options.reconstruct.time, "360");
  EXPECT_EQ(options.reconstruct.options, std::vector<std::string>{"--gres=gpu:1"});
  EXPECT_EQ(options.max_running, 10);
  EXPECT_EQ(options.poll_seconds, 7.5);
  EXPECT_EQ(testing::ErrorOf([&] {
              cluster::ApplySlurmTable(options, nlohmann::json::parse(R"({"nodes": 2})"), "e.toml");
            }),
            "e.toml: [slurm] nodes: unknown Slurm setting");
  EXPECT_EQ(testing::ErrorOf([&] {
              cluster::ApplySlurmTable(options, nlohmann::json::parse(R"({"time": ["1", "2"]})"),
                                       "e.toml");
            }),
            "e.toml: [slurm] time: expected one value, not a list");
  EXPECT_EQ(testing::ErrorOf([&] {
              cluster::ApplySlurmTable(options, nlohmann::json::parse(R"({"qos": true})"),
                                       "e.toml");
            }),
            "e.toml: [slurm] qos: expected a string or a number, not true");
  EXPECT_EQ(testing::ErrorOf([&] {
              cluster::ApplySlurmTable(options, nlohmann::json::parse(R"({"time": "2h"})"),
                                       "e.toml");
            }),
            "e.toml: [slurm] time: '2h' is not a Slurm time (minutes, h:mm:ss, days-hh:mm:ss)");
}

TEST(SlurmArgs, BadValuesAreOneLineUsageErrors) {
  EXPECT_EQ(Parse({"--executor", "slurm", "--slurm-time", "2h"}).error,
            "--slurm-time: '2h' is not a Slurm time (minutes, h:mm:ss, days-hh:mm:ss)");
  EXPECT_EQ(Parse({"--executor", "slurm", "--slurm-mem", "4 GB"}).error,
            "--slurm-mem: '4 GB' is not a Slurm memory size (megabytes, or a number with K, M, "
            "G or T)");
  EXPECT_EQ(Parse({"--executor", "slurm", "--slurm-cpus-per-task", "-1"}).error,
            "--slurm-cpus-per-task: '-1' is not a count (0, 1, 2, ...)");
  EXPECT_EQ(Parse({"--executor", "slurm", "--slurm-option", "exclusive"}).error,
            "--slurm-option: 'exclusive' is not an sbatch option (it must start with -)");
  EXPECT_EQ(Parse({"--executor", "slurm", "--slurm-option=--array=1-3"}).error,
            "--slurm-option '--array=1-3': rephoto sets --array itself (see docs/cluster.md)");
  EXPECT_EQ(Parse({"--executor", "slurm", "--slurm-account", "a b"}).error,
            "--slurm-account: 'a b' holds a space or control character");
  EXPECT_EQ(Parse({"--executor", "slurm", "--slurm-poll", "0"}).error,
            "--slurm-poll: '0' is not a number of seconds in (0, 3600]");
  cluster::SlurmOptions options;
  EXPECT_EQ(testing::ErrorOf(
                [&] { cluster::SetSlurmSetting(options, "nodes", "2", "x: [slurm] nodes"); }),
            "x: [slurm] nodes: unknown Slurm setting");
  EXPECT_THROW(Parse({"--executor", "pbs"}), CLI::ValidationError);
}

TEST(SlurmArgs, OutcomePrintsJobIdsOnStdoutWhenNotFinished) {
  cluster::RunOutcome outcome;
  outcome.groups.resize(2);
  outcome.groups[0].name = "reconstruct";
  outcome.groups[0].followed_jobs = {"811"};
  outcome.groups[1].name = "views";
  outcome.groups[1].submitted_jobs = {"812", "813"};
  cluster::TaskOutcome failed;
  failed.id = "fold_01/reconstruct";
  failed.state = cluster::TaskState::kFailed;
  failed.message = "exit code 1 on node n3";
  failed.job = "811_1";
  failed.log_file = "/runs/a/slurm/811_1.log";
  outcome.groups[0].tasks = {failed};
  outcome.finished = false;
  ::testing::internal::CaptureStdout();
  ::testing::internal::CaptureStderr();
  PrintSlurmOutcome(outcome, "rephoto evaluate --config exp.toml --executor slurm");
  const std::string out = ::testing::internal::GetCapturedStdout();
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(out, "slurm jobs: 812 813 811\n");
  EXPECT_NE(err.find("rephoto: warning: slurm: failed: fold_01/reconstruct: exit code 1 on node "
                     "n3 (job 811_1); log: /runs/a/slurm/811_1.log\n"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("run `rephoto evaluate --config exp.toml --executor slurm` again"),
            std::string::npos)
      << err;
}

}  // namespace
}  // namespace rephoto::cli
