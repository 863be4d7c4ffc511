// `rephoto live` as a process: kill -9 in the middle of a capture and restart resumes from the
// run folder without redoing registered photos; a second writer on the same run is refused.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>

#include <chrono>
#include <nlohmann/json.hpp>
#include <cmath>
#include <set>
#include <thread>

#include "rephoto/core/file.h"
#include "rephoto/live/demo_capture.h"
#include "rephoto/testing/testing.h"

namespace rephoto::live {
namespace {
namespace fs = std::filesystem;

struct Record {
  std::string name, status;
  bool has_depth = false;
};

std::vector<Record> Records(const fs::path& jsonl) {
  std::vector<Record> r;
  if (!fs::exists(jsonl)) return r;
  const std::string text = ReadFileToString(jsonl);
  size_t start = 0;
  while (true) {
    const size_t end = text.find('\n', start);
    if (end == std::string::npos) break;
    const nlohmann::json j = nlohmann::json::parse(text.substr(start, end - start));
    r.push_back({j["name"], j["status"], j.value("has_depth", false)});
    start = end + 1;
  }
  return r;
}

pid_t Start(const std::vector<std::string>& args, const fs::path& log) {
  const pid_t pid = fork();
  if (pid == 0) {
    setpgid(0, 0);
    FILE* f = freopen(log.c_str(), "w", stderr);
    (void)f;
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    execv(argv[0], argv.data());
    _exit(127);
  }
  return pid;
}

TEST(LiveCliTest, KillNineAndRestartResumes) {
  const fs::path base = testing::MakeTempDir();
  const fs::path watch = base / "watch", run = base / "run";
  fs::create_directories(watch);
  DemoCapture capture(320, 240);
  const int n = 7;
  for (int k = 0; k < n; ++k) {
    const double a = k * 0.3;
    capture.Drop(watch, fmt::format("p{}", k), LookAt({3.2 * std::cos(a), 3.2 * std::sin(a), 1.5}, {0, 0, 0.45}), k);
  }
  const std::vector<std::string> args = {REPHOTO_CLI, "live", "--watch", watch.string(), "--out",
                                         run.string(), "--stable-seconds", "0.2",
                                         "--exit-when-idle", "4", "--predict-width", "320"};
  const pid_t first = Start(args, base / "first.log");
  // Wait until 3 photos are registered, then kill -9 the whole process group.
  const auto t0 = std::chrono::steady_clock::now();
  size_t registered = 0;
  while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(120)) {
    registered = 0;
    for (const Record& r : Records(run / "live.jsonl")) registered += r.status == "registered";
    if (registered >= 3) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_GE(registered, 3u) << ReadFileToString(base / "first.log");
  // A second writer is refused at once while the first runs.
  const testing::ShellOutcome second = testing::RunShell(
      std::string(REPHOTO_CLI) + " live --watch '" + watch.string() + "' --out '" + run.string() +
      "' --exit-when-idle 1");
  EXPECT_NE(second.exit_code, 0);
  EXPECT_NE(second.err.find("another rephoto live"), std::string::npos) << second.err;
  kill(-first, SIGKILL);
  int status = 0;
  waitpid(first, &status, 0);
  ASSERT_TRUE(WIFSIGNALED(status));
  const std::vector<Record> before = Records(run / "live.jsonl");
  std::set<std::string> done;  // registered with their depth map before the kill
  for (const Record& r : before)
    if (r.status == "registered" && r.has_depth) done.insert(r.name);
  ASSERT_FALSE(done.empty());
  // Restart: resumes, finishes the others, redoes none of the finished ones.
  const pid_t again = Start(args, base / "again.log");
  waitpid(again, &status, 0);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << ReadFileToString(base / "again.log");
  const std::vector<Record> after = Records(run / "live.jsonl");
  std::set<std::string> final_registered;
  for (size_t i = 0; i < after.size(); ++i) {
    if (after[i].status == "registered") final_registered.insert(after[i].name);
    if (i >= before.size()) {
      EXPECT_EQ(done.count(after[i].name), 0u) << after[i].name << " was redone";
    }
  }
  EXPECT_EQ(final_registered.size(), static_cast<size_t>(n));
  EXPECT_TRUE(fs::exists(run / "live.json"));
}

}  // namespace
}  // namespace rephoto::live
