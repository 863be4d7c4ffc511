// What a resumed `--executor slurm` call costs on the submitting node when everything has
// finished: RunTaskGroups reads RUN/slurm/jobs.json and every task's result file, decides that
// nothing is to be submitted, and calls no Slurm program (they are /bin/false here, so a call
// would fail the benchmark). Peer: reading and parsing the same result files alone.
// Also: writing the batch script of an array of N tasks, and (with a running cluster) a whole
// array end to end against sbatch --wait alone.
#include <benchmark/benchmark.h>
#include <fmt/format.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>

#include "rephoto/cluster/slurm.h"
#include "rephoto/cluster/slurm_text.h"
#include "rephoto/core/file.h"

namespace {

namespace fs = std::filesystem;
using namespace rephoto;
using namespace rephoto::cluster;

// k = n/8 reconstruction tasks, n view tasks (each after its fold's reconstruction), one
// aggregation; all finished, with result files as the batch scripts write them.
struct FinishedRun {
  fs::path dir;
  std::vector<TaskGroup> groups;

  explicit FinishedRun(int views) {
    dir = fs::temp_directory_path() / fmt::format("rephoto-bench-cluster-{}-{}", ::getpid(), views);
    fs::remove_all(dir);
    groups.resize(3);
    groups[0].name = "reconstruct";
    groups[1].name = "views";
    groups[2].name = "aggregate";
    const int folds = std::max(1, views / 8);
    for (int f = 0; f < folds; ++f) {
      groups[0].tasks.push_back(
          {fmt::format("fold_{:03}/reconstruct", f),
           {"/usr/bin/rephoto", "evaluate", "--only", fmt::format("reconstruct:{}", f)},
           "",
           std::nullopt});
    }
    for (int v = 0; v < views; ++v) {
      groups[1].tasks.push_back(
          {fmt::format("fold_{:03}/views/{}", v % folds, v),
           {"/usr/bin/rephoto", "evaluate", "--only", fmt::format("views:{}:{}:1", v % folds, v)},
           "",
           std::vector<std::string>{fmt::format("fold_{:03}/reconstruct", v % folds)}});
    }
    groups[2].tasks.push_back(
        {"aggregate", {"/usr/bin/rephoto", "evaluate", "--only", "aggregate"}, "", std::nullopt});
    const fs::path slurm = dir / "slurm";
    for (size_t g = 0; g < groups.size(); ++g) {
      for (size_t i = 0; i < groups[g].tasks.size(); ++i) {
        const Task& task = groups[g].tasks[i];
        WriteTextFileAtomically(
            ResultPath(slurm, task.id),
            fmt::format(R"({{"schema":"rephoto.cluster.result/1","id":"{}","fingerprint":"{}",)"
                        R"("submission":{},"job":"{}","index":{},"node":"n1","exit_code":0,)"
                        R"("start":"2026-11-25T15:48:52Z","end":"2026-11-25T15:48:55Z",)"
                        R"("seconds":3}})",
                        task.id, TaskFingerprint(task), g + 1, 100 + g, i));
      }
    }
  }
  ~FinishedRun() { fs::remove_all(dir); }
};

SlurmOptions NoSlurm() {
  SlurmOptions options;
  options.commands = {"/bin/false", "/bin/false", "/bin/false", "/bin/false", "/bin/false"};
  return options;
}

void BM_ResumeFinishedRun(benchmark::State& state) {
  const FinishedRun run(static_cast<int>(state.range(0)));
  const SlurmOptions options = NoSlurm();
  for (auto _ : state) {
    const RunOutcome outcome = RunTaskGroups(run.dir, run.groups, options);
    if (outcome.submitted != 0 || !outcome.finished) state.SkipWithError("not all done");
    benchmark::DoNotOptimize(outcome);
  }
  state.counters["tasks"] =
      static_cast<double>(run.groups[0].tasks.size() + run.groups[1].tasks.size() + 1);
}
BENCHMARK(BM_ResumeFinishedRun)->Arg(100)->Arg(1000)->Arg(10000)->Unit(benchmark::kMillisecond);

// Peer: only reading and parsing the result files.
void BM_ReadResultFiles(benchmark::State& state) {
  const FinishedRun run(static_cast<int>(state.range(0)));
  for (auto _ : state) {
    size_t ok = 0;
    for (const TaskGroup& group : run.groups) {
      for (const Task& task : group.tasks) {
        const auto result =
            ParseTaskResult(ReadFileToString(ResultPath(run.dir / "slurm", task.id)));
        ok += result && result->exit_code == 0 ? 1 : 0;
      }
    }
    benchmark::DoNotOptimize(ok);
  }
}
BENCHMARK(BM_ReadResultFiles)->Arg(100)->Arg(1000)->Arg(10000)->Unit(benchmark::kMillisecond);

void BM_ArrayScript(benchmark::State& state) {
  const FinishedRun run(static_cast<int>(state.range(0)));
  SlurmResources resources;
  ArraySpec spec{.submission = 1,
                 .group = "views",
                 .slurm_dir = run.dir / "slurm",
                 .resources = &resources,
                 .job_name = "rephoto-views"};
  for (const Task& task : run.groups[1].tasks) spec.tasks.push_back(&task);
  for (auto _ : state) {
    const std::string script = MakeArrayScript(spec, SbatchArguments(spec, "s.sh"));
    benchmark::DoNotOptimize(script);
  }
}
BENCHMARK(BM_ArrayScript)->Arg(1000)->Unit(benchmark::kMillisecond);

// End to end on a running cluster (SLURM_CONF set, e.g. by `eval "$(scripts/slurm-cluster.sh
// env DIR)"`; skipped otherwise): one group of N tasks that run /bin/true, submitted, followed
// (poll 0.25 s) and collected by RunTaskGroups. Peer: the same array submitted with sbatch
// alone (`--wrap /bin/true`, no wrapper script, no result files), followed by a shell loop that
// calls squeue every 0.25 s until it is gone. (`sbatch --wait` is no peer: it backs off to
// polling every 32 s.)
bool HaveCluster(benchmark::State& state) {
  if (std::getenv("SLURM_CONF") != nullptr) return true;
  state.SkipWithError("SLURM_CONF is not set: start scripts/slurm-cluster.sh first");
  return false;
}

void BM_SlurmArrayRunTaskGroups(benchmark::State& state) {
  if (!HaveCluster(state)) return;
  const int tasks = static_cast<int>(state.range(0));
  std::vector<TaskGroup> groups(1);
  groups[0].name = "work";
  for (int i = 0; i < tasks; ++i) {
    groups[0].tasks.push_back({fmt::format("t{}", i), {"/bin/true"}, "", std::nullopt});
  }
  SlurmOptions options;
  options.poll_seconds = 0.25;
  int round = 0;
  for (auto _ : state) {
    const fs::path dir =
        fs::temp_directory_path() / fmt::format("rephoto-bench-slurm-{}-{}", ::getpid(), round++);
    const RunOutcome outcome = RunTaskGroups(dir, groups, options);
    if (outcome.Count(TaskState::kDone) != static_cast<size_t>(tasks)) {
      state.SkipWithError("not every task finished");
    }
    state.PauseTiming();
    fs::remove_all(dir);
    state.ResumeTiming();
  }
}
BENCHMARK(BM_SlurmArrayRunTaskGroups)
    ->Arg(50)
    ->Unit(benchmark::kSecond)
    ->UseRealTime()
    ->Iterations(3);

void BM_SlurmArraySbatchSqueue(benchmark::State& state) {
  if (!HaveCluster(state)) return;
  const std::string command = fmt::format(
      "j=$(sbatch --parsable --array=0-{} --output=/dev/null --wrap /bin/true) && "
      "while [ -n \"$(squeue -h -j $j -t PD,CF,R,CG -o %i)\" ]; do sleep 0.25; done",
      state.range(0) - 1);
  for (auto _ : state) {
    if (std::system(command.c_str()) != 0) state.SkipWithError("sbatch or squeue failed");
  }
}
BENCHMARK(BM_SlurmArraySbatchSqueue)
    ->Arg(50)
    ->Unit(benchmark::kSecond)
    ->UseRealTime()
    ->Iterations(3);

}  // namespace

BENCHMARK_MAIN();
