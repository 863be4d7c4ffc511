// `rephoto serve`: the benchmark's HTTP server (cpp-httplib, Debian libcpp-httplib-dev), a thin
// layer over Store (store.h), Submissions (submissions.h), the API documents (api.h) and the
// pages (pages.h). Routes and status codes: docs/benchmark.md.
//
// Files: a published file is found by (dataset, name) in the database and read from the path
// recorded there; no URL path is ever joined to a folder. Error images of a submission are
// found by (submission id, test-image stem, metric) checked against the dataset's record.
// Requests: bodies above ServerOptions::max_body are refused with 413 by the HTTP library before
// they are read; a POST is handled on its HTTP thread only up to queueing (Submissions::Submit);
// scoring runs on the Submissions workers.
// Thread safety: Run() blocks its caller; Stop() may be called from any thread.
#pragma once

#include <atomic>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>

#include "rephoto/benchmark/store.h"
#include "rephoto/benchmark/submissions.h"

namespace httplib {
class Server;
}

namespace rephoto::benchmark {

struct ServerOptions {
  std::string host = "127.0.0.1";
  int port = 8080;  // 0 = any free port (see Server::port)
  int http_threads = 8;
  int scoring_workers = 1;
  size_t max_body = size_t{512} << 20;  // bytes of one request body
  SubmissionLimits limits;
};

class Server {
 public:
  // Opens the store in `root` (must exist) and sets up the routes; does not listen yet.
  Server(const std::filesystem::path& root, const ServerOptions& options);
  ~Server();
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  // Takes the root's server lock (<root>/.rephoto-serve, flock(2), held until destruction; a
  // second server on the same root is refused with an Error), binds the address (throws Error
  // when it cannot), starts the scoring workers (re-queueing unfinished submissions) and
  // returns the port.
  int Bind();
  // Serves until Stop(). Bind() first. Returns at once when Stop() came first.
  void Run();
  // Makes Run() return (or not start) and waits until it has returned. Not from a handler.
  void Stop();
  int port() const { return port_; }

  Store& store() { return store_; }
  Submissions& submissions() { return submissions_; }

 private:
  void SetupApiRoutes();
  void SetupPageRoutes();

  // The root's server lock: declared first, so released after the workers stopped.
  struct RootLock {
    ~RootLock();
    int fd = -1;
  };
  RootLock lock_;
  ServerOptions options_;
  Store store_;
  Submissions submissions_;
  std::unique_ptr<httplib::Server> http_;
  int port_ = 0;
  std::mutex run_mutex_;
  bool stop_requested_ = false;
  std::atomic<bool> running_ = false;
};

}  // namespace rephoto::benchmark
