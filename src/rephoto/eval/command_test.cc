#include "rephoto/eval/command.h"

#include <gtest/gtest.h>

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
  const CommandOutcome outcome = RunShellCommand("printf '%s|' " + ShellQuote(nasty), log, "test");
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
  CommandOutcome outcome = RunShellCommand("echo hello; echo oops >&2; exit 3", log, "header");
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
  const CommandOutcome outcome = RunShellCommand("sleep 30; echo late", dir / "log", "t");
  interrupter.join();
  RequestInterrupt(false);
  EXPECT_TRUE(outcome.interrupted);
  EXPECT_LT(outcome.seconds, 10.0);
  EXPECT_EQ(LastLogLine(dir / "log"), "");
}

}  // namespace
}  // namespace rephoto::eval
