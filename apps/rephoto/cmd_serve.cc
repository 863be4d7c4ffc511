// rephoto serve --root DIR [--listen HOST:PORT] [--threads N] [--scoring-workers N]
//               [--max-body BYTES] [--max-extracted BYTES] [--max-files N]
//               [--rate-limit N] [--rate-window SECONDS] [--header-timeout SECONDS]
//               [--request-timeout SECONDS]
//               [--keep-alive-timeout SECONDS] [--max-connections-per-address N]
//               [--access-log FILE|-]
// Serves the benchmark folder DIR over HTTP (rephoto/service/server.h; API in
// docs/benchmark.md) until SIGINT or SIGTERM. Scores submissions in the background; on start,
// re-queues the submissions a previous run left queued or half-scored.
#include <fmt/format.h>
#include <pthread.h>
#include <signal.h>

#include <filesystem>
#include <memory>
#include <string>
#include <thread>

#include "command.h"
#include "rephoto/service/server.h"
#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"

namespace rephoto::cli {
namespace {

struct ServeArguments {
  std::string root;
  std::string listen = "127.0.0.1:8080";
  service::ServerOptions options;
};

void ParseListen(const std::string& text, service::ServerOptions* options) {
  const size_t colon = text.rfind(':');
  REPHOTO_CHECK_USAGE(colon != std::string::npos && colon > 0, "--listen '{}': use HOST:PORT",
                      text);
  options->host = text.substr(0, colon);
  try {
    size_t used = 0;
    options->port = std::stoi(text.substr(colon + 1), &used);
    REPHOTO_CHECK_USAGE(used == text.size() - colon - 1, "--listen '{}': bad port", text);
  } catch (const std::logic_error&) {
    throw UsageError(fmt::format("--listen '{}': bad port", text));
  }
  REPHOTO_CHECK_USAGE(options->port >= 0 && options->port <= 65535, "--listen '{}': bad port",
                      text);
}

int RunServe(ServeArguments& args) {
  REPHOTO_CHECK_USAGE(std::filesystem::is_directory(args.root), "--root {}: not a folder",
                      args.root);
  ParseListen(args.listen, &args.options);
  // SIGINT/SIGTERM are taken by one thread (sigwait) that stops the server; every other thread
  // inherits the blocked mask.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGTERM);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
  service::Server server(args.root, args.options);
  const int port = server.Bind();
  LogInfo(fmt::format("serving {} on http://{}:{}/", args.root, args.options.host, port));
  std::thread stopper([&] {
    int signal_number = 0;
    sigwait(&signals, &signal_number);
    LogInfo("stopping");
    server.Stop();
  });
  server.Run();
  pthread_kill(stopper.native_handle(), SIGTERM);
  stopper.join();
  return static_cast<int>(ExitCode::kOk);
}

CommandRunner SetupServe(CLI::App& app) {
  auto args = std::make_shared<ServeArguments>();
  service::ServerOptions& o = args->options;
  app.add_option("--root", args->root, "The benchmark folder (rephoto benchmark add-dataset)")
      ->required();
  app.add_option("--listen", args->listen, "HOST:PORT (port 0: any free port)")
      ->capture_default_str();
  app.add_option("--threads", o.http_threads, "HTTP threads")->capture_default_str();
  app.add_option("--scoring-workers", o.scoring_workers, "Threads scoring submissions")
      ->check(CLI::Range(1, 64))
      ->capture_default_str();
  app.add_option("--max-body", o.max_body, "Largest request body in bytes (413 above)")
      ->capture_default_str();
  app.add_option("--max-extracted", o.limits.archive.max_bytes,
                 "Largest total size of the extracted renders in bytes (413 above)")
      ->capture_default_str();
  app.add_option("--max-files", o.limits.archive.max_files, "Most files in one archive (413)")
      ->capture_default_str();
  app.add_option("--rate-limit", o.limits.max_per_window,
                 "Submission attempts (accepted or refused) per participant per --rate-window "
                 "(429 above)")
      ->capture_default_str();
  app.add_option("--rate-window", o.limits.window_seconds, "Rate-limit window in seconds")
      ->capture_default_str();
  app.add_option("--header-timeout", o.header_timeout,
                 "Seconds for a request's line and headers (408 after)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--request-timeout", o.request_timeout,
                 "Seconds one request (line, headers, body) may take (408 after)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--keep-alive-timeout", o.keep_alive_timeout,
                 "Seconds an idle connection stays open")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-connections-per-address", o.max_connections_per_address,
                 "Connections at once from one client address (503 above)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--access-log", o.access_log,
                 "Access log in common log format: a file (appended), - for stdout, '' for none")
      ->capture_default_str();
  return [args]() { return RunServe(*args); };
}

}  // namespace

REPHOTO_COMMAND(85, "serve",
                "Serve a benchmark folder over HTTP (datasets, submissions, "
                "leaderboard)",
                SetupServe);

}  // namespace rephoto::cli
