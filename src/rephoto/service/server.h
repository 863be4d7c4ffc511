// `rephoto serve`: the benchmark's HTTP server (cpp-httplib, Debian libcpp-httplib-dev), a thin
// layer over Store (store.h), Submissions (submissions.h), the API documents (api.h) and the
// pages (pages.h). Routes and status codes: docs/benchmark.md.
//
// Files: a published file is found by (dataset, name) in the database and read from the path
// recorded there; no URL path is ever joined to a folder. Error images of a submission are
// found by (submission id, test-image stem, metric) checked against the dataset's record.
// Requests, in the order the server looks at them (docs/benchmark.md, "Threat model"):
//   - connections: at most max_connections_per_address at once from one client address (more
//     get 503 and are closed); a request's line and headers must arrive within header_timeout
//     seconds and the whole request (with its body) within request_timeout, else it is answered
//     408 (when nothing was written yet) and the connection closed; an idle kept-alive
//     connection is closed after keep_alive_timeout. A connection holds an HTTP thread while
//     it is open, so http_threads / max_connections_per_address addresses are needed to hold
//     every thread, each for at most header_timeout seconds without sending its headers;
//     more than that is for a front-end (nginx, docs/benchmark.md);
//   - after the headers, before any body byte is read: the path and every query parameter must
//     be clean text (text.h; 400); a Content-Encoding other than identity is refused (415);
//     only POST .../submissions may have a body (a body elsewhere: 400; other POST/PUT/...:
//     404/405); the connection is closed (and the response says "Connection: close") after
//     every request refused there and every upload, so an unread body is never taken for the
//     next request and a proxy never reuses such a connection;
//   - POST .../submissions: the token (401), the declared Content-Length (413 above max_body),
//     the dataset (404) and the rate limit (429; Submissions::Begin records the attempt) are
//     checked before the body is read; the body (raw, chunked or without a length; a multipart
//     form must declare its length, 411) is streamed to a file in the upload's folder and
//     refused with 413 as soon as max_body bytes were received, so memory stays bounded by a
//     few buffers per connection; then Submissions::Finish (400/413) and 202.
// Every handler catches everything: a request is answered 4xx/5xx and the process lives; JSON
// is serialised with invalid UTF-8 replaced, so stored text never makes a response fail.
// Logs: one access-log line per answered request (common log format: address, time, method
// and path without the query, status, bytes; never a header, so never a token) to
// ServerOptions::access_log, and one warning line (stderr, core/progress.h) per refusal
// (status >= 400 and refused connections) with its reason.
// The listening socket has SO_REUSEADDR only (cpp-httplib's default also sets SO_REUSEPORT,
// which lets a second server share the port): a port in use is an Error naming it.
// Scoring runs on the Submissions workers, never on an HTTP thread.
// Thread safety: Run() blocks its caller; Stop() may be called from any thread.
#pragma once

#include <atomic>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>

#include "rephoto/service/store.h"
#include "rephoto/service/submissions.h"

namespace httplib {
class Server;
struct Request;
struct Response;
class ContentReader;
}  // namespace httplib

namespace rephoto::service {

struct ServerOptions {
  std::string host = "127.0.0.1";
  int port = 8080;  // 0 = any free port (see Server::port)
  // One per open connection (cpp-httplib's model); cheap (a stack each), so many.
  int http_threads = 32;
  int scoring_workers = 1;
  size_t max_body = size_t{512} << 20;  // bytes of one request body
  double header_timeout = 10;           // seconds for a request's line and headers
  double request_timeout = 300;         // seconds for one request: line, headers and body
  double keep_alive_timeout = 5;        // seconds an idle connection stays open
  int max_connections_per_address = 4;  // connections at once from one client address
  // Access log: a file (appended), "-" for stdout, "" for none.
  std::string access_log = "-";
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
  void ReceiveSubmission(const httplib::Request& req, httplib::Response& res,
                         const httplib::ContentReader& content_reader);

  // The root's server lock: declared first, so released after the workers stopped.
  struct RootLock {
    ~RootLock();
    int fd = -1;
  };
  RootLock lock_;
  ServerOptions options_;
  Store store_;
  Submissions submissions_;
  class AccessLog;
  std::unique_ptr<AccessLog> access_log_;
  std::unique_ptr<httplib::Server> http_;
  int port_ = 0;
  std::mutex run_mutex_;
  bool stop_requested_ = false;
  std::atomic<bool> running_ = false;
};

}  // namespace rephoto::service
