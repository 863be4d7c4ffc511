// Shared helpers for rephoto's tests (linked into every test by rephoto_test()).
//
// Thread safety: MakeTempDir, MakeRng and the test-name lookups read gtest's current test and are
// meant for the test's main thread; the others are free functions without shared state (WriteFile
// and RunShell touch only the paths they are given).
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <string_view>

namespace rephoto::testing {

// The repository root (tests run with it as working directory).
std::filesystem::path SourceDir();

// ../shared/data relative to the repository root, where the real datasets live.
std::filesystem::path SharedDataDir();

// A fresh, empty folder for the current test, removed when the test program exits normally.
std::filesystem::path MakeTempDir();

// A random engine seeded from the current test's full name: reproducible per test, different
// between tests, independent of the order tests run in.
std::mt19937_64 MakeRng();

// The message of the rephoto::Error that `f` throws, or "(no error)" when it throws none (other
// exceptions propagate): for tests of one-line error messages.
std::string ErrorOf(const std::function<void()>& f);

// `text` with the first occurrence of `from` replaced by `to`; a test failure when `from` does
// not occur (for tests that break one field of a valid file).
std::string Replace(std::string text, const std::string& from, const std::string& to);

// Writes `content` (bytes, as given) to `path`, creating its folders; returns `path`.
std::filesystem::path WriteFile(const std::filesystem::path& path, std::string_view content);

// What a shell command did: its exit status (-1 when a signal ended it) and its output.
struct ShellOutcome {
  int exit_code = -1;
  std::string err;
  std::string out;
};

// Runs `command` with /bin/sh, stdout and stderr captured through files in a temp folder.
ShellOutcome RunShell(const std::string& command);

}  // namespace rephoto::testing

// Skips the current test with a message when a dataset folder under ../shared/data is missing.
#define REPHOTO_REQUIRE_DATA(relative)                                                             \
  do {                                                                                             \
    if (!std::filesystem::exists(::rephoto::testing::SharedDataDir() / (relative))) {              \
      GTEST_SKIP() << "dataset not found: " << (::rephoto::testing::SharedDataDir() / (relative)); \
    }                                                                                              \
  } while (false)
