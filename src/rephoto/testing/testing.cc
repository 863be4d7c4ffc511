#include "rephoto/testing/testing.h"

#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <functional>
#include <string>

#include "rephoto/core/error.h"

namespace rephoto::testing {
namespace fs = std::filesystem;

fs::path SourceDir() { return fs::path(REPHOTO_SOURCE_DIR); }

fs::path SharedDataDir() { return SourceDir().parent_path() / "shared" / "data"; }

namespace {
// The test program's temporary folder, removed at exit. The removal is registered with atexit
// after the path is constructed, so it runs before the path's own destructor (a static object
// cleaning up in its destructor would see the path already destroyed).
fs::path& TempRoot() {
  static fs::path root = [] {
    fs::path p = fs::temp_directory_path() / ("rephoto-test-" + std::to_string(::getpid()));
    fs::create_directories(p);
    return p;
  }();
  static const bool registered = [] {
    std::atexit([] {
      std::error_code ec;
      fs::remove_all(TempRoot(), ec);
    });
    return true;
  }();
  (void)registered;
  return root;
}
}  // namespace

fs::path MakeTempDir() {
  static std::atomic<int> counter{0};
  const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = info ? std::string(info->test_suite_name()) + "." + info->name() : "test";
  for (char& c : name) {
    if (c == '/') c = '_';
  }
  fs::path dir = TempRoot() / (name + "-" + std::to_string(counter++));
  fs::create_directories(dir);
  return dir;
}

std::mt19937_64 MakeRng() {
  const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
  std::string name = info ? std::string(info->test_suite_name()) + "." + info->name() : "";
  return std::mt19937_64(std::hash<std::string>{}(name) ^ 0x5eed2017ULL);
}

std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace rephoto::testing
