// The live page in a real browser: a live session with 3 photos served on a free port, and
// tests/browser/live_page.py (Debian's headless chromium over the DevTools protocol) checking
// that the page shows them and then updates to 5 photos without a reload, while this test adds
// 2 photos once the script signals it is watching. Needs `chromium` and `python3-websocket`.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <fmt/format.h>
#include <thread>

#include "rephoto/core/file.h"
#include "rephoto/live/closed_loop.h"
#include "rephoto/live/demo_capture.h"
#include "rephoto/live/live_server.h"
#include "rephoto/live/live_session.h"
#include "rephoto/testing/testing.h"

namespace rephoto::live {
namespace {
namespace fs = std::filesystem;

TEST(LiveBrowserTest, PageUpdatesWithoutReload) {
  ASSERT_EQ(std::system("command -v chromium >/dev/null && /usr/bin/python3 -c 'import "
                        "websocket' 2>/dev/null"),
            0)
      << "install chromium and python3-websocket (scripts/install-deps.sh)";
  const fs::path base = testing::MakeTempDir();
  const fs::path watch = base / "watch", run = base / "run", signal = base / "go";
  fs::create_directories(watch);
  DemoCapture capture(240, 180);
  LiveOptions o;
  o.watch = watch;
  o.out = run;
  o.predict_width = 240;
  o.depth_width = 240;
  o.candidates = 100;
  LiveSession session(o);
  auto drop = [&](int k) {
    const double a = k * 0.3;
    const std::string stem = fmt::format("p{}", k);
    capture.Drop(watch, stem, LookAt({3.2 * std::cos(a), 3.2 * std::sin(a), 1.5}, {0, 0, 0.45}), k);
    session.HandleReady(stem + ".png");
  };
  for (int k = 0; k < 3; ++k) drop(k);
  testing::WriteFile(watch / "notes.txt", "no photo");
  session.HandleReady("notes.txt");
  // The plot live-experiment leaves in each run folder (two steps of made-up figures).
  ClosedLoopResult loop;
  for (Sequence* s : {&loop.suggested, &loop.ring, &loop.random_median}) {
    s->name = s == &loop.suggested ? "suggested" : s == &loop.ring ? "ring" : "random_median";
    s->steps = {StepFigures{.added = 0, .unseen = 0.5, .heldout_error_all = 0.8},
                StepFigures{.added = 1, .unseen = 0.3, .heldout_error_all = 0.6}};
  }
  WriteTextFileAtomically(run / "closed_loop.svg", ClosedLoopSvg(loop));
  LiveServer server(session, run);
  const int port = server.Bind("127.0.0.1", 0);
  std::thread http([&] { server.Run(); });
  std::thread capture_thread([&] {
    const auto t0 = std::chrono::steady_clock::now();
    while (!fs::exists(signal) && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(120))
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    if (fs::exists(signal)) {
      drop(3);
      drop(4);
    }
  });
  const fs::path log = base / "browser.log";
  const std::string command =
      fmt::format("timeout 240 /usr/bin/python3 '{}' http://127.0.0.1:{} '{}' >'{}' 2>&1",
                  (testing::SourceDir() / "tests" / "browser" / "live_page.py").string(), port,
                  signal.string(), log.string());
  const int status = std::system(command.c_str());
  capture_thread.join();
  server.Stop();
  http.join();
  EXPECT_EQ(status, 0) << ReadFileToString(log);
  EXPECT_NE(ReadFileToString(log).find("all checks passed"), std::string::npos)
      << ReadFileToString(log);
}

}  // namespace
}  // namespace rephoto::live
