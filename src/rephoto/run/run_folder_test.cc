#include "rephoto/run/run_folder.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <thread>

#include "rephoto/core/error.h"
#include "rephoto/testing/testing.h"

namespace rephoto::run {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

using testing::ErrorOf;

TEST(RunFolder, CreatesAMissingFolderAndMarksIt) {
  const fs::path dir = testing::MakeTempDir() / "new" / "run";
  {
    RunFolder folder = OpenRunFolder(dir, "compare");
    EXPECT_TRUE(folder.locked());
    std::ifstream in(dir / kRunMarkFile);
    std::string line;
    std::getline(in, line);
    EXPECT_EQ(line, "rephoto compare run folder");
    std::getline(in, line);
    EXPECT_EQ(line, "pid " + std::to_string(::getpid()));
  }
  // Reopened by the same kind after the first writer is gone (resume).
  EXPECT_TRUE(OpenRunFolder(dir, "compare").locked());
}

TEST(RunFolder, RefusesAFolderItDidNotMake) {
  const fs::path dir = testing::MakeTempDir();
  std::ofstream(dir / "thesis.tex") << "years of work";
  EXPECT_EQ(ErrorOf([&] { OpenRunFolder(dir, "compare"); }),
            dir.string() +
                ": the folder is not empty and holds no rephoto compare run; use an empty or "
                "new --out");
  EXPECT_FALSE(fs::exists(dir / kRunMarkFile));
  // A caller's legacy test accepts folders written before the mark existed.
  EXPECT_TRUE(OpenRunFolder(dir, "compare", [](const fs::path&) { return true; }).locked());
}

TEST(RunFolder, RefusesAnotherKindOfRun) {
  const fs::path dir = testing::MakeTempDir();
  OpenRunFolder(dir, "evaluate");
  EXPECT_THAT(ErrorOf([&] { OpenRunFolder(dir, "compare"); }),
              HasSubstr("holds another kind of run ('rephoto evaluate run folder'), not a "
                        "rephoto compare run"));
}

TEST(RunFolder, RefusesAFileOrASymlinkedMark) {
  const fs::path dir = testing::MakeTempDir();
  std::ofstream(dir / "file") << "x";
  EXPECT_THAT(ErrorOf([&] { OpenRunFolder(dir / "file", "compare"); }),
              HasSubstr("exists and is not a folder"));
  const fs::path run = dir / "run";
  fs::create_directories(run);
  fs::create_symlink(dir / "file", run / kRunMarkFile);
  EXPECT_THAT(ErrorOf([&] { OpenRunFolder(run, "compare"); }), HasSubstr("is not a regular file"));
}

TEST(RunFolder, SecondWriterInTheSameProcessIsRefused) {
  const fs::path dir = testing::MakeTempDir();
  RunFolder first = OpenRunFolder(dir, "evaluate");
  EXPECT_EQ(ErrorOf([&] { OpenRunFolder(dir, "evaluate"); }),
            fmt::format("{}: another rephoto evaluate (pid {}) is writing this run folder; wait "
                        "for it or use another --out",
                        dir.string(), ::getpid()));
  first = RunFolder();  // released
  EXPECT_TRUE(OpenRunFolder(dir, "evaluate").locked());
}

TEST(RunFolder, KillNineReleasesTheFolderAtOnce) {
  const fs::path dir = testing::MakeTempDir();
  int ready[2];
  ASSERT_EQ(::pipe(ready), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    RunFolder folder = OpenRunFolder(dir, "evaluate");
    const char byte = 1;
    (void)!::write(ready[1], &byte, 1);
    ::pause();
    ::_exit(0);
  }
  char byte = 0;
  ASSERT_EQ(::read(ready[0], &byte, 1), 1);
  EXPECT_THAT(ErrorOf([&] { OpenRunFolder(dir, "evaluate"); }),
              HasSubstr(fmt::format("another rephoto evaluate (pid {})", child)));
  ::kill(child, SIGKILL);
  int status = 0;
  ::waitpid(child, &status, 0);
  EXPECT_TRUE(OpenRunFolder(dir, "evaluate").locked());
  ::close(ready[0]);
  ::close(ready[1]);
}

TEST(RunFolder, TheLockIsNotInheritedByCommands) {
  const fs::path dir = testing::MakeTempDir();
  RunFolder folder = OpenRunFolder(dir, "evaluate");
  // A command started by the run (exec'd) must not keep the folder locked after rephoto dies.
  const std::string command =
      fmt::format("ls -l /proc/self/fd | grep -c '{}' || true", (dir / kRunMarkFile).string());
  FILE* pipe = ::popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  char buffer[32] = {};
  ASSERT_NE(std::fgets(buffer, sizeof buffer, pipe), nullptr);
  ::pclose(pipe);
  EXPECT_EQ(std::string(buffer), "0\n");
}

}  // namespace
}  // namespace rephoto::run
