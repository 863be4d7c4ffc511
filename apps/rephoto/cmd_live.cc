// rephoto live --watch DIR --out RUN [--listen HOST:PORT] [--suggestions K] [--colmap]
//              [--predict-width W] [--depth-width W] [--neighbors N] [--blur-ratio R]
//              [--sidecar-wait S] [--stable-seconds S] [--exit-when-idle S]
// Follows DIR while photos arrive: each new photo is predicted from the earlier ones before it
// joins them, the errors are projected onto the current model and the next views are suggested
// (src/rephoto/live/live_session.h, docs/live.md). With --listen, serves the live page and
// GET /api/live. Stops on SIGINT/SIGTERM, or after --exit-when-idle seconds without work.
#include <fmt/format.h>
#include <pthread.h>
#include <signal.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <memory>
#include <string>
#include <thread>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"
#include "rephoto/live/colmap_registrar.h"
#include "rephoto/live/live_server.h"
#include "rephoto/live/live_session.h"
#include "rephoto/live/watcher.h"

namespace rephoto::cli {
namespace {
namespace fs = std::filesystem;

struct LiveArguments {
  live::LiveOptions options;
  std::string watch, out, listen;
  double stable_seconds = 3;
  double exit_when_idle = 0;
  bool colmap = false;
  int colmap_bootstrap = 0;
  int colmap_bundle_every = 0;
  int colmap_min_inliers = 0;
  std::string colmap_camera;
  int colmap_exhaustive_up_to = -1;
  std::string colmap_binary = "colmap";
};

CommandRunner SetupLive(CLI::App& app) {
  auto args = std::make_shared<LiveArguments>();
  live::LiveOptions& o = args->options;
  app.add_option("--watch", args->watch, "Folder the photos arrive in")->required()->check(CLI::ExistingDirectory);
  app.add_option("--out", args->out, "Run folder (created; resumed when it holds a live run)")->required();
  app.add_option("--listen", args->listen, "Serve the live page on HOST:PORT (e.g. 127.0.0.1:8090)");
  app.add_option("--suggestions", o.suggestions, "Next views to suggest")->capture_default_str();
  app.add_option("--candidates", o.candidates, "Candidate poses for the suggestions")->capture_default_str();
  app.add_option("--predict-width", o.predict_width, "Width of predictions and error images (pixels)")->capture_default_str();
  app.add_option("--depth-width", o.depth_width, "Plane-sweep working width (pixels)")->capture_default_str();
  app.add_option("--neighbors", o.neighbors, "Photos a prediction is rendered from")->capture_default_str();
  app.add_option("--blur-ratio", o.blur_ratio, "A photo sharper than this times the median is kept (0 = no blur check)")->capture_default_str();
  app.add_option("--sidecar-wait", o.sidecar_wait, "Seconds a photo waits for its <stem>.json pose")->capture_default_str();
  app.add_option("--stable-seconds", args->stable_seconds, "A file whose size did not change for this long is complete")->capture_default_str();
  app.add_option("--exit-when-idle", args->exit_when_idle, "Exit after this many seconds without new files (0 = run until stopped)")->capture_default_str();
  app.add_flag("--colmap", args->colmap, "Register photos without a sidecar with COLMAP (colmap_registrar.h)");
  app.add_option("--colmap-bootstrap", args->colmap_bootstrap, "Photos the initial COLMAP reconstruction waits for (0 = default)");
  app.add_option("--colmap-bundle-every", args->colmap_bundle_every,
                 "Global COLMAP bundle adjustment every N registrations (0 = never; refined poses are taken over)")
      ->capture_default_str();
  app.add_option("--colmap-min-inliers", args->colmap_min_inliers,
                 "Absolute-pose inliers COLMAP needs to place a photo (0 = default 15; COLMAP's own default is 30)");
  app.add_option("--colmap-camera", args->colmap_camera,
                 "Known intrinsics, kept fixed: \"MODEL p1,p2,...\" in COLMAP's names and order "
                 "(e.g. \"PINHOLE 3310.4,3325.5,317.2,201.1\"; default: COLMAP guesses and refines them)");
  app.add_option("--colmap-exhaustive-up-to", args->colmap_exhaustive_up_to,
                 "Match a new photo with every earlier one while there are at most N, then with chosen ones (default 30)");
  app.add_option("--colmap-binary", args->colmap_binary, "The colmap program")->capture_default_str();
  return [args]() {
    live::LiveOptions options = args->options;
    options.watch = args->watch;
    options.out = args->out;
    options.show_progress = true;
    std::unique_ptr<live::Registrar> registrar;
    if (args->colmap) {
      live::ColmapRegistrarOptions co;
      co.workspace = fs::path(args->out) / "colmap";
      co.colmap = args->colmap_binary;
      if (args->colmap_bootstrap > 0) co.bootstrap = args->colmap_bootstrap;
      co.bundle_every = args->colmap_bundle_every;
      if (args->colmap_min_inliers > 0) co.min_inliers = args->colmap_min_inliers;
      if (!args->colmap_camera.empty()) live::ParseColmapCamera(args->colmap_camera, &co);
      if (args->colmap_exhaustive_up_to >= 0) co.match_all_up_to = args->colmap_exhaustive_up_to;
      registrar = live::MakeColmapRegistrar(co);
      options.registrar = registrar.get();
    }
    sigset_t signals;
    sigemptyset(&signals);
    sigaddset(&signals, SIGINT);
    sigaddset(&signals, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &signals, nullptr);
    std::atomic<bool> stop = false;
    live::LiveSession session(options);
    live::FolderWatcher watcher(options.watch, args->stable_seconds);
    std::unique_ptr<live::LiveServer> server;
    std::thread http;
    if (!args->listen.empty()) {
      const auto [host, port] = live::ParseListen(args->listen);
      server = std::make_unique<live::LiveServer>(session, options.out);
      const int bound = server->Bind(host, port);
      LogInfo(fmt::format("live page: http://{}:{}/", host, bound));
      http = std::thread([&] { server->Run(); });
    }
    std::thread waiter([&] {
      int signal_number = 0;
      sigwait(&signals, &signal_number);
      stop = true;
    });
    auto last_work = std::chrono::steady_clock::now();
    // After kIdleSeconds without a new file the engine may work for the photos it has not
    // placed (LiveSession::Idle), once per pause; an idle exit waits for that.
    constexpr double kIdleSeconds = 2;
    const double idle_after =
        args->exit_when_idle > 0 ? std::min(kIdleSeconds, args->exit_when_idle) : kIdleSeconds;
    bool idle_done = false;
    const auto idle_for = [&] {
      return std::chrono::duration<double>(std::chrono::steady_clock::now() - last_work).count();
    };
    int code = static_cast<int>(ExitCode::kOk);
    try {
      while (!stop) {
        const std::vector<std::string> ready = watcher.Poll(0.3);
        for (const std::string& name : ready) {
          if (stop) break;
          session.HandleReady(name);
          last_work = std::chrono::steady_clock::now();
          idle_done = false;
        }
        if (session.Tick()) last_work = std::chrono::steady_clock::now();
        if (!stop && !idle_done && idle_for() >= idle_after) {
          idle_done = true;
          if (session.Idle()) last_work = std::chrono::steady_clock::now();
        }
        if (args->exit_when_idle > 0 && idle_done && session.waiting() == 0 &&
            idle_for() >= args->exit_when_idle)
          break;
      }
    } catch (...) {
      if (server) server->Stop();
      if (http.joinable()) http.join();
      pthread_kill(waiter.native_handle(), SIGTERM);
      waiter.join();
      throw;
    }
    if (server) server->Stop();
    if (http.joinable()) http.join();
    if (!stop) pthread_kill(waiter.native_handle(), SIGTERM);
    waiter.join();
    const nlohmann::json api = session.Api();
    size_t registered = 0;
    for (const auto& p : api["photos"]) registered += p["status"] == "registered";
    fmt::print("{} photos registered of {} files; run folder {}\n", registered, api["photos"].size(),
               args->out);
    return code;
  };
}

}  // namespace

REPHOTO_COMMAND(57, "live",
                "Follow a capture as it happens: predict each new photo, suggest the next views",
                SetupLive);

}  // namespace rephoto::cli
