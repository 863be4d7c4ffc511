// The benchmark's pages in a real browser: starts a server with one dataset and two scored
// submissions and runs tests/browser/benchmark_pages.mjs (puppeteer-core driving Debian's
// headless chromium; see that file for the checks). Needs `node`, `chromium` and
// `npm ci --prefix tests/browser` (scripts/test.sh does it); fails saying so when one is missing.
#include <gtest/gtest.h>

#include <thread>

#include "rephoto/benchmark/server.h"
#include "rephoto/benchmark/test_fixture.h"
#include "rephoto/core/file.h"
#include "rephoto/testing/testing.h"

namespace rephoto::benchmark {
namespace {
namespace fs = std::filesystem;

TEST(PagesBrowserTest, PagesWorkInHeadlessChromium) {
  const fs::path tooling = rephoto::testing::SourceDir() / "tests" / "browser";
  ASSERT_TRUE(fs::exists(tooling / "node_modules" / "puppeteer-core"))
      << "run: npm ci --prefix tests/browser (scripts/test.sh does)";
  ASSERT_EQ(std::system("command -v node >/dev/null && command -v chromium >/dev/null"), 0)
      << "install nodejs and chromium (scripts/install-deps.sh)";
  std::mt19937_64 rng = rephoto::testing::MakeRng();
  const fs::path base = rephoto::testing::MakeTempDir();
  const fs::path root = base / "root";
  fs::create_directories(root);
  testing::MakeTinyScene(base / "scene", 6, 64, 48, rng);
  ServerOptions options;
  options.port = 0;
  Server server(root, options);
  testing::AddTinyDataset(server.store(), base / "scene", "tiny");
  server.store().AddParticipant("alice");
  const ParticipantRecord alice = *server.store().Participants().begin();
  const int port = server.Bind();
  std::thread thread([&] { server.Run(); });
  server.submissions().Submit(alice, "tiny", testing::RendersFromPhotos(root, "tiny", 0.0, rng),
                              "exact", "renders equal to the photos");
  server.submissions().Submit(alice, "tiny", testing::RendersFromPhotos(root, "tiny", 0.1, rng),
                              "noisy", "photos plus uniform noise");
  ASSERT_TRUE(server.submissions().WaitIdle(120));

  const fs::path log = base / "browser.log";
  const std::string command = "timeout 180 node '" + (tooling / "benchmark_pages.mjs").string() +
                              "' http://127.0.0.1:" + std::to_string(port) + " >'" + log.string() +
                              "' 2>&1";
  const int status = std::system(command.c_str());
  server.Stop();
  thread.join();
  EXPECT_EQ(status, 0) << ReadFileToString(log);
  EXPECT_NE(ReadFileToString(log).find("all checks passed"), std::string::npos)
      << ReadFileToString(log);
}

}  // namespace
}  // namespace rephoto::benchmark
