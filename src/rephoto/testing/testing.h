// Shared helpers for rephoto's tests (linked into every test by rephoto_test()).
#pragma once

#include <gtest/gtest.h>

#include <filesystem>
#include <functional>
#include <random>
#include <string>

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

}  // namespace rephoto::testing

// Skips the current test with a message when a dataset folder under ../shared/data is missing.
#define REPHOTO_REQUIRE_DATA(relative)                                                             \
  do {                                                                                             \
    if (!std::filesystem::exists(::rephoto::testing::SharedDataDir() / (relative))) {              \
      GTEST_SKIP() << "dataset not found: " << (::rephoto::testing::SharedDataDir() / (relative)); \
    }                                                                                              \
  } while (false)
