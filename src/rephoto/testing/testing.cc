#include "rephoto/testing/testing.h"

#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <sstream>
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

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at == std::string::npos) return text;
  return text.replace(at, from.size(), to);
}

fs::path WriteFile(const fs::path& path, std::string_view content) {
  if (path.has_parent_path()) fs::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary);
  out.write(content.data(), static_cast<std::streamsize>(content.size()));
  EXPECT_TRUE(out.good()) << path;
  return path;
}

namespace {
std::string ReadWholeFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}
}  // namespace

ShellOutcome RunShell(const std::string& command) {
  const fs::path dir = MakeTempDir();
  const std::string redirected =
      command + " >'" + (dir / "stdout").string() + "' 2>'" + (dir / "stderr").string() + "'";
  const int status = std::system(redirected.c_str());
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, ReadWholeFile(dir / "stderr"),
          ReadWholeFile(dir / "stdout")};
}

}  // namespace rephoto::testing
