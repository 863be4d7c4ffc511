// The benchmark's pages in a real browser: starts a server with one dataset and two scored
// submissions and runs tests/browser/benchmark_pages.py (Debian's headless chromium driven
// through the DevTools protocol with Debian's python3-websocket; see that file for the checks).
// Needs `chromium` and `python3-websocket` (scripts/install-deps.sh); fails saying so when one
// is missing.
#include <gtest/gtest.h>

#include <thread>

#include "rephoto/service/server.h"
#include "rephoto/service/test_fixture.h"
#include "rephoto/core/file.h"
#include "rephoto/testing/testing.h"

namespace rephoto::service {
namespace {
namespace fs = std::filesystem;

TEST(PagesBrowserTest, PagesWorkInHeadlessChromium) {
  const fs::path tooling = rephoto::testing::SourceDir() / "tests" / "browser";
  ASSERT_EQ(std::system("command -v chromium >/dev/null && /usr/bin/python3 -c 'import "
                        "websocket' 2>/dev/null"),
            0)
      << "install chromium and python3-websocket (scripts/install-deps.sh)";
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
  const std::string command = "timeout 180 /usr/bin/python3 '" +
                              (tooling / "benchmark_pages.py").string() +
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
}  // namespace rephoto::service
