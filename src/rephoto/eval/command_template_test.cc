#include "rephoto/eval/command_template.h"

#include <gtest/gtest.h>
#include <signal.h>

#include <thread>

#include "rephoto/core/file.h"
#include "rephoto/testing/testing.h"

namespace rephoto::eval {
namespace {

namespace fs = std::filesystem;

TEST(CommandTest, ShellQuoteSurvivesTheShell) {
  EXPECT_EQ(ShellQuote("a b"), "'a b'");
  EXPECT_EQ(ShellQuote("it's"), "'it'\\''s'");
  // Run through /bin/sh: printf prints the one argument it got back unchanged.
  const fs::path dir = testing::MakeTempDir();
  const std::string nasty = "a b 'c' \"d\" $HOME `x` \\ {e}";
  const fs::path log = dir / "log.txt";
  const ShellOutcome outcome = RunShellCommand("printf '%s|' " + ShellQuote(nasty), log, "test");
  ASSERT_TRUE(outcome.ok());
  EXPECT_EQ(LastLogLine(log), nasty + "|");
}

TEST(CommandTest, PlaceholdersAreSubstitutedAndQuoted) {
  const std::map<std::string, std::string> values = {{"out", "/tmp/my dir"}, {"fold", "3"}};
  EXPECT_EQ(SubstitutePlaceholders("cp x {out}/m.ply # {fold}", values, "--reconstruct"),
            "cp x '/tmp/my dir'/m.ply # '3'");
  // Literal braces, shell variables and awk programs pass through.
  EXPECT_EQ(SubstitutePlaceholders("echo {{out}} ${HOME} awk '{print $1}' {}", values, "x"),
            "echo {out} ${HOME} awk '{print $1}' {}");
}

TEST(CommandTest, UnknownPlaceholderListsTheKnownOnes) {
  try {
    TemplatePlaceholders("run {train} {trian}", {"train", "out"}, "--reconstruct");
    FAIL() << "no error";
  } catch (const UsageError& e) {
    EXPECT_STREQ(e.what(),
                 "--reconstruct: unknown placeholder {trian} (known: {train}, {out}; write {{ "
                 "and }} for literal braces)");
  }
  EXPECT_EQ(TemplatePlaceholders("{out} {train} {out}", {"train", "out"}, "x"),
            (std::vector<std::string>{"out", "train"}));
}

TEST(CommandTest, ExitStatusAndOutputAreCaptured) {
  const fs::path dir = testing::MakeTempDir();
  const fs::path log = dir / "logs" / "a.log";
  ShellOutcome outcome = RunShellCommand("echo hello; echo oops >&2; exit 3", log, "header");
  EXPECT_EQ(outcome.exit_status, 3);
  EXPECT_FALSE(outcome.ok());
  const std::string text = ReadFileToString(log);
  EXPECT_NE(text.find("# header"), std::string::npos);
  EXPECT_NE(text.find("hello\noops\n"), std::string::npos);
  EXPECT_EQ(LastLogLine(log), "oops");

  outcome = RunShellCommand("no_such_command_rephoto_test", log, "header");
  EXPECT_EQ(outcome.exit_status, 127);
  EXPECT_NE(LastLogLine(log).find("not found"), std::string::npos);
}

TEST(CommandTest, InterruptStopsTheCommandGroup) {
  const fs::path dir = testing::MakeTempDir();
  RequestInterrupt(false);
  std::thread interrupter([] {
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    RequestInterrupt(true);
  });
  // A child of the shell (sleep) must be stopped too: the whole process group gets SIGTERM.
  const ShellOutcome outcome = RunShellCommand("sleep 30; echo late", dir / "log", "t");
  interrupter.join();
  RequestInterrupt(false);
  EXPECT_TRUE(outcome.interrupted);
  EXPECT_LT(outcome.seconds, 10.0);
  EXPECT_EQ(LastLogLine(dir / "log"), "");
}

TEST(CommandTest, TimeoutEndsTheWholeProcessGroup) {
  const fs::path dir = testing::MakeTempDir();
  RequestInterrupt(false);
  // The shell starts a stage that ignores SIGTERM and records its pid: the timeout must end it
  // too (SIGKILL to the group once the shell is gone), not leave it running.
  const std::string pid_file = (dir / "pid").string();
  const ShellOutcome outcome = RunShellCommand(
      "(trap '' TERM; exec sleep 1000) & echo $! > " + ShellQuote(pid_file) + "; wait", dir / "log",
      "t", 0.3);
  EXPECT_TRUE(outcome.timed_out);
  EXPECT_FALSE(outcome.interrupted);
  EXPECT_FALSE(outcome.ok());
  EXPECT_LT(outcome.seconds, 8.0);
  EXPECT_EQ(LastLogLine(dir / "log"),
            "# rephoto: timed out after 0.3 s (--command-timeout); stopping the command's "
            "process group");
  const pid_t stage = std::stoi(ReadFileToString(pid_file));
  // Reaped by init once killed; give the kernel a moment.
  bool gone = false;
  for (int i = 0; i < 100 && !gone; ++i) {
    gone = ::kill(stage, 0) != 0 ||
           ReadFileToString("/proc/" + std::to_string(stage) + "/stat").find(") Z") !=
               std::string::npos;
    if (!gone) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  EXPECT_TRUE(gone) << "the stage that ignored SIGTERM still runs";
}

TEST(CommandTest, NoTimeoutByDefault) {
  const fs::path dir = testing::MakeTempDir();
  const ShellOutcome outcome = RunShellCommand("sleep 0.3", dir / "log", "t");
  EXPECT_TRUE(outcome.ok());
  EXPECT_FALSE(outcome.timed_out);
}

}  // namespace
}  // namespace rephoto::eval
