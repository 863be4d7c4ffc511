#include "rephoto/service/server.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <fmt/format.h>
#include <httplib.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/file.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <map>
#include <memory>
#include <regex>
#include <thread>

#include "rephoto/service/api.h"
#include "rephoto/service/pages.h"
#include "rephoto/service/text.h"
#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"

namespace rephoto::service {
namespace fs = std::filesystem;
namespace {

using Clock = std::chrono::steady_clock;

const char* const kSubmissionRoute = R"(/api/datasets/([^/]+)/submissions)";
// Requests served on one connection before it is closed.
constexpr size_t kMaxRequestsPerConnection = 100;

void SendJson(httplib::Response& res, int status, const nlohmann::json& json) {
  res.status = status;
  res.set_content(JsonText(json) + "\n", "application/json");
}

void SendError(httplib::Response& res, int status, const std::string& message) {
  SendJson(res, status, {{"error", Printable(message, 2000)}});
}

void SendHtml(httplib::Response& res, const std::optional<std::string>& html) {
  if (!html) {
    res.status = 404;
    res.set_content(NotFoundPage(), "text/html; charset=utf-8");
    return;
  }
  res.set_content(*html, "text/html; charset=utf-8");
}

// Runs a handler's body so that nothing escapes: Refused answers its status, anything else 500
// (logged). Every route goes through it.
template <class Body>
void Guarded(httplib::Response& res, Body&& body) noexcept {
  try {
    try {
      body();
    } catch (const Refused& refused) {
      SendError(res, refused.status, refused.what());
    } catch (const std::exception& error) {
      LogWarning(fmt::format("request failed: {}", Printable(error.what(), 1000)));
      SendError(res, 500, "internal error");
    } catch (...) {
      LogWarning("request failed: unknown exception");
      SendError(res, 500, "internal error");
    }
  } catch (...) {
    res.status = 500;  // even the error could not be formatted (out of memory)
    res.body.clear();
  }
}

// Streams a file from disk in 64 KiB chunks (tar files may be large).
void SendFile(httplib::Response& res, const fs::path& path, const std::string& mime) {
  auto in = std::make_shared<std::ifstream>(path, std::ios::binary);
  std::error_code error;
  const size_t size = fs::file_size(path, error);
  if (!*in || error) {
    SendError(res, 500, "a published file cannot be read");
    return;
  }
  res.set_content_provider(size, mime, [in](size_t offset, size_t length, httplib::DataSink& sink) {
    std::vector<char> buffer(std::min<size_t>(length, 1 << 16));
    in->seekg(static_cast<std::streamoff>(offset));
    in->read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    const auto count = in->gcount();
    if (count <= 0) return false;
    sink.write(buffer.data(), static_cast<size_t>(count));
    return true;
  });
}

// The bearer token of the request, or "".
std::string BearerToken(const httplib::Request& req) {
  const std::string header = req.get_header_value("Authorization");
  const std::string prefix = "Bearer ";
  if (header.size() <= prefix.size() || header.compare(0, prefix.size(), prefix) != 0) return "";
  return header.substr(prefix.size());
}

// The declared Content-Length (an unparsable one counts as too large).
uint64_t DeclaredLength(const httplib::Request& req) {
  const std::string text = req.get_header_value("Content-Length");
  char* end = nullptr;
  errno = 0;
  const unsigned long long value = std::strtoull(text.c_str(), &end, 10);
  if (text.empty() || end != text.c_str() + text.size() || errno != 0 || text[0] == '-') {
    return UINT64_MAX;
  }
  return value;
}

std::string PeerAddress(int sock) {
  sockaddr_storage address{};
  socklen_t length = sizeof(address);
  if (getpeername(sock, reinterpret_cast<sockaddr*>(&address), &length) != 0) return "?";
  char text[INET6_ADDRSTRLEN] = "?";
  if (address.ss_family == AF_INET) {
    inet_ntop(AF_INET, &reinterpret_cast<sockaddr_in*>(&address)->sin_addr, text, sizeof(text));
  } else if (address.ss_family == AF_INET6) {
    inet_ntop(AF_INET6, &reinterpret_cast<sockaddr_in6*>(&address)->sin6_addr, text, sizeof(text));
  }
  return text;
}

// Waits until `sock` has one of `events` or `timeout` passed; false on timeout or error.
bool WaitSocket(int sock, short events, Clock::duration timeout) {
  const Clock::time_point end = Clock::now() + timeout;
  for (;;) {
    // Rounded up: a wait of less than a millisecond must not end at once.
    const auto left = std::chrono::ceil<std::chrono::milliseconds>(end - Clock::now());
    if (left.count() <= 0) return false;
    pollfd fd{sock, events, 0};
    const int rc = poll(&fd, 1, static_cast<int>(std::min<int64_t>(left.count(), 1 << 30)));
    if (rc > 0) return true;
    if (rc == 0) return false;
    if (errno != EINTR) return false;
  }
}

// Closes a connection so that a response already written reaches the client: our side is shut
// down first, then what the client still sends is read and dropped until it closes, for at most
// `linger` and 4 MiB (closing with unread data would send a reset, which can destroy the
// response in the client's buffer).
void CloseConnection(int sock, Clock::duration linger) {
  shutdown(sock, SHUT_WR);
  const Clock::time_point end = Clock::now() + linger;
  char buffer[16384];
  size_t drained = 0;
  while (drained < (size_t{4} << 20)) {
    // What has arrived already is dropped without waiting; more is waited for until `linger`.
    ssize_t n = recv(sock, buffer, sizeof(buffer), MSG_DONTWAIT);
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      const auto left = end - Clock::now();
      if (left <= Clock::duration::zero() || !WaitSocket(sock, POLLIN, left)) break;
      n = recv(sock, buffer, sizeof(buffer), MSG_DONTWAIT);
    }
    if (n <= 0) break;
    drained += static_cast<size_t>(n);
  }
  close(sock);
}

// httplib's Stream over a connected socket with a deadline for reading the current request
// (request line, headers, body): past it every read fails, as a read timeout would. Buffered:
// httplib reads request lines one byte at a time.
class DeadlineStream : public httplib::Stream {
 public:
  DeadlineStream(int sock, Clock::duration read_timeout, Clock::duration write_timeout)
      : sock_(sock), read_timeout_(read_timeout), write_timeout_(write_timeout) {}

  void StartRequest(Clock::duration limit) {
    deadline_ = Clock::now() + limit;
    expired_ = false;
    written_ = 0;
  }
  // The headers are in: the body may take until `limit` from the request's start.
  void SetDeadline(Clock::time_point deadline) { deadline_ = deadline; }
  bool expired() const { return expired_; }
  size_t written() const { return written_; }
  bool Buffered() const { return begin_ < end_; }
  // Whether the connection must be closed after the current response.
  bool close_after = false;

  bool is_readable() const override { return Buffered() || WaitRead(); }
  bool is_writable() const override { return WaitSocket(sock_, POLLOUT, write_timeout_); }
  ssize_t read(char* ptr, size_t size) override {
    if (!Buffered()) {
      if (!WaitRead()) return -1;
      if (size >= sizeof(buffer_)) return Receive(ptr, size);
      const ssize_t n = Receive(buffer_, sizeof(buffer_));
      if (n <= 0) return n;
      begin_ = 0;
      end_ = static_cast<size_t>(n);
    }
    const size_t count = std::min(size, end_ - begin_);
    std::memcpy(ptr, buffer_ + begin_, count);
    begin_ += count;
    return static_cast<ssize_t>(count);
  }
  ssize_t write(const char* ptr, size_t size) override {
    if (!is_writable()) return -1;
    ssize_t n;
    do {
      n = send(sock_, ptr, size, MSG_NOSIGNAL);
    } while (n < 0 && errno == EINTR);
    if (n > 0) written_ += static_cast<size_t>(n);
    return n;
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    Address(getpeername, ip, port);
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    Address(getsockname, ip, port);
  }
  socket_t socket() const override { return sock_; }

 private:
  bool WaitRead() const {
    const auto left = deadline_ - Clock::now();
    if (left <= Clock::duration::zero()) {
      expired_ = true;
      return false;
    }
    const bool ready = WaitSocket(sock_, POLLIN, std::min(left, read_timeout_));
    if (!ready && deadline_ - Clock::now() < std::chrono::milliseconds(2)) expired_ = true;
    return ready;
  }
  ssize_t Receive(char* ptr, size_t size) {
    ssize_t n;
    do {
      n = recv(sock_, ptr, size, 0);
    } while (n < 0 && errno == EINTR);
    return n;
  }
  template <class Get>
  void Address(Get get, std::string& ip, int& port) const {
    sockaddr_storage address{};
    socklen_t length = sizeof(address);
    ip.clear();
    port = 0;
    if (get(sock_, reinterpret_cast<sockaddr*>(&address), &length) != 0) return;
    char text[INET6_ADDRSTRLEN] = "";
    if (address.ss_family == AF_INET) {
      const auto* in = reinterpret_cast<sockaddr_in*>(&address);
      inet_ntop(AF_INET, &in->sin_addr, text, sizeof(text));
      port = ntohs(in->sin_port);
    } else if (address.ss_family == AF_INET6) {
      const auto* in = reinterpret_cast<sockaddr_in6*>(&address);
      inet_ntop(AF_INET6, &in->sin6_addr, text, sizeof(text));
      port = ntohs(in->sin6_port);
    }
    ip = text;
  }

  int sock_;
  Clock::duration read_timeout_, write_timeout_;
  Clock::time_point deadline_ = Clock::time_point::max();
  mutable bool expired_ = false;
  size_t written_ = 0;
  char buffer_[16384];
  size_t begin_ = 0, end_ = 0;
};

// The stream of the connection the calling HTTP thread serves (set by
// GuardedHttpServer::process_and_close_socket): handlers mark it to be closed after the
// response.
thread_local DeadlineStream* current_stream = nullptr;

// Closes the connection after the response to `req`, and says so in the response
// ("Connection: close", which cpp-httplib writes when the request carries it), so that a proxy
// never reuses the connection (nginx would answer 502 for a request sent on it).
void CloseAfterResponse(const httplib::Request& req) {
  if (current_stream) current_stream->close_after = true;
  if (req.get_header_value("Connection") != "close") {
    // The Request is httplib's own non-const object, handed to handlers as const.
    auto& headers = const_cast<httplib::Request&>(req).headers;
    headers.erase("Connection");
    headers.emplace("Connection", "close");
  }
}

// The current request's whole deadline (set with its start).
thread_local Clock::time_point request_deadline;

// Whether the current request's deadline passed while its body was read.
bool RequestExpired() { return current_stream && current_stream->expired(); }

// Called when the headers are in: the body may take until the request's whole deadline.
void HeadersReceived() {
  if (current_stream) current_stream->SetDeadline(request_deadline);
}

std::string JsonErrorOf(const httplib::Response& res) {
  if (res.body.empty() || res.body.size() > 4096 || res.body.front() != '{') return "";
  const nlohmann::json json = nlohmann::json::parse(res.body, nullptr, false);
  if (json.is_discarded() || !json.contains("error") || !json["error"].is_string()) return "";
  return json["error"];
}

// A field of a log line: printable, and no '"' (which would end a CLF field).
std::string LogField(std::string_view text) {
  std::string out = Printable(text, 500);
  for (size_t at = out.find('"'); at != std::string::npos; at = out.find('"', at)) {
    out.replace(at, 1, "\\x22");
  }
  return out;
}

}  // namespace

// One line per answered request in the common log format, and the refusals as warnings.
class Server::AccessLog {
 public:
  explicit AccessLog(const std::string& target) {
    if (target == "-") {
      file_ = stdout;
    } else if (!target.empty()) {
      file_ = std::fopen(target.c_str(), "a");
      REPHOTO_CHECK(file_, "{}: cannot open the access log ({})", target, std::strerror(errno));
      owned_ = true;
    }
  }
  ~AccessLog() {
    if (owned_) std::fclose(file_);
  }
  void Request(const httplib::Request& req, const httplib::Response& res) {
    size_t bytes = res.body.size();
    if (res.has_header("Content-Length")) {
      bytes = std::strtoull(res.get_header_value("Content-Length").c_str(), nullptr, 10);
    }
    Line(req.remote_addr, fmt::format("{} {} HTTP/1.1", LogField(req.method), LogField(req.path)),
         res.status, bytes);
    if (res.status >= 400) {
      Refusal(req.remote_addr, fmt::format("{} {}", LogField(req.method), LogField(req.path)),
              res.status, JsonErrorOf(res));
    }
  }
  // A connection answered without an HTTP request (too many connections, deadline).
  void Connection(const std::string& address, int status, size_t bytes, const std::string& why) {
    Line(address, "-", status, bytes);
    Refusal(address, "-", status, why);
  }

 private:
  void Line(const std::string& address, const std::string& request, int status, size_t bytes) {
    if (!file_) return;
    const std::time_t now = std::time(nullptr);
    std::tm utc{};
    gmtime_r(&now, &utc);
    char time[64];
    std::strftime(time, sizeof(time), "%d/%b/%Y:%H:%M:%S +0000", &utc);
    const std::string line =
        fmt::format("{} - - [{}] \"{}\" {} {}\n", LogField(address), time, request, status, bytes);
    std::lock_guard lock(mutex_);
    std::fputs(line.c_str(), file_);
    std::fflush(file_);
  }
  void Refusal(const std::string& address, const std::string& request, int status,
               const std::string& why) {
    LogWarning(fmt::format("refused {} to {} \"{}\": {}", status, LogField(address), request,
                           why.empty() ? "-" : LogField(why)));
  }

  std::FILE* file_ = nullptr;
  bool owned_ = false;
  std::mutex mutex_;
};

namespace {

// cpp-httplib's server with our own connection loop (httplib::Server::process_and_close_socket
// is its documented customisation point, as its SSLServer uses it): the per-address bound, the
// per-request deadline and closing after errors (see server.h).
class GuardedHttpServer : public httplib::Server {
 public:
  GuardedHttpServer(
      const ServerOptions& options,
      std::function<void(const std::string&, int, size_t, const std::string&)> log_connection)
      : options_(options), log_connection_(std::move(log_connection)) {}

 public:
  // cpp-httplib 0.11 listens with a backlog of 5: a burst of connections overflows it and
  // their SYNs are retried a second later. Linux takes a new backlog from a second listen().
  void SetBacklog(int backlog) { ::listen(svr_sock_, backlog); }

 private:
  bool process_and_close_socket(socket_t sock) override {
    const std::string address = PeerAddress(sock);
    bool admitted = false;
    {
      std::lock_guard lock(mutex_);
      int& count = connections_[address];
      if (count < options_.max_connections_per_address) {
        ++count;
        admitted = true;
      }
    }
    if (!admitted) {
      const std::string body =
          JsonText({{"error", fmt::format("more than {} connections at once from one address",
                                          options_.max_connections_per_address)}});
      const std::string response = fmt::format(
          "HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\nRetry-After: "
          "5\r\nConnection: close\r\nContent-Length: {}\r\n\r\n{}",
          body.size(), body);
      const ssize_t sent =
          send(sock, response.data(), response.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
      log_connection_(address, 503, sent > 0 ? body.size() : 0,
                      "too many connections from this address");
      // No linger: a refusal must cost the thread nothing (an address opening many connections
      // queues them all before the threads that refuse each).
      CloseConnection(sock, Clock::duration::zero());
      return true;
    }
    const auto seconds = [](double s) {
      return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
    };
    DeadlineStream stream(sock, seconds(std::min(options_.request_timeout, 60.0)), seconds(30));
    current_stream = &stream;
    for (size_t count = kMaxRequestsPerConnection; count > 0 && is_running(); --count) {
      if (!stream.Buffered() && !WaitSocket(sock, POLLIN, seconds(options_.keep_alive_timeout))) {
        break;  // idle
      }
      // The request line and headers within header_timeout, all of it within request_timeout
      // (the pre-routing handler extends the deadline once the headers are in).
      const Clock::time_point start = Clock::now();
      stream.StartRequest(seconds(std::min(options_.header_timeout, options_.request_timeout)));
      request_deadline = start + seconds(options_.request_timeout);
      bool connection_closed = false;
      bool ok = false;
      try {
        ok = process_request(stream, count == 1, connection_closed, nullptr);
      } catch (...) {
        ok = false;  // our handlers catch everything; this is httplib's own failure
      }
      if (stream.expired() && stream.written() == 0) {
        const std::string body =
            JsonText({{"error", fmt::format("the request did not arrive within {} s",
                                            options_.request_timeout)}});
        const std::string response = fmt::format(
            "HTTP/1.1 408 Request Timeout\r\nContent-Type: application/json\r\nConnection: "
            "close\r\nContent-Length: {}\r\n\r\n{}",
            body.size(), body);
        send(sock, response.data(), response.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
        log_connection_(address, 408, body.size(),
                        fmt::format("request not complete within its deadline ({} s for the "
                                    "headers, {} s in all)",
                                    options_.header_timeout, options_.request_timeout));
        break;
      }
      if (!ok || connection_closed || stream.close_after) break;
    }
    current_stream = nullptr;
    {
      std::lock_guard lock(mutex_);
      if (--connections_[address] == 0) connections_.erase(address);
    }
    // After an error or a POST the client may still be sending a body: linger so that the
    // response is not destroyed by a reset. An idle or finished connection is closed at once.
    CloseConnection(sock, stream.close_after ? std::chrono::seconds(1) : Clock::duration::zero());
    return true;
  }

  ServerOptions options_;
  std::function<void(const std::string&, int, size_t, const std::string&)> log_connection_;
  std::mutex mutex_;
  std::map<std::string, int> connections_;
};

}  // namespace

Server::Server(const fs::path& root, const ServerOptions& options)
    : options_(options),
      store_(root),
      submissions_(store_, options.limits, options.scoring_workers),
      access_log_(std::make_unique<AccessLog>(options.access_log)) {
  REPHOTO_CHECK(options.request_timeout > 0 && options.header_timeout > 0 &&
                    options.keep_alive_timeout > 0 && options.max_connections_per_address > 0,
                "the request, header and keep-alive timeouts and the connections per address "
                "must be positive");
  http_ = std::make_unique<GuardedHttpServer>(
      options,
      [this](const std::string& address, int status, size_t bytes, const std::string& why) {
        access_log_->Connection(address, status, bytes, why);
      });
  const int threads = std::max(1, options.http_threads);
  http_->new_task_queue = [threads] { return new httplib::ThreadPool(threads); };
  http_->set_payload_max_length(options.max_body);
  // Without it a response written in two parts waits for the client's delayed ACK (~25 ms).
  http_->set_tcp_nodelay(true);
  // SO_REUSEADDR only: httplib's default adds SO_REUSEPORT, with which a second server binds the
  // same port and the kernel splits the connections between the two.
  http_->set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  });
  http_->set_logger([this](const httplib::Request& req, const httplib::Response& res) {
    try {
      access_log_->Request(req, res);
    } catch (...) {
    }
  });
  http_->set_exception_handler(
      [](const httplib::Request&, httplib::Response& res, std::exception_ptr error) {
        Guarded(res, [&] { std::rethrow_exception(error); });
      });
  http_->set_error_handler([](const httplib::Request& req, httplib::Response& res) {
    Guarded(res, [&] {
      if (!res.body.empty()) return;
      if (res.status == 413) {
        SendError(res, 413, "the request body exceeds the server's limit");
      } else if (res.status == 404) {
        SendError(res, 404, "not found");
      } else {
        SendError(res, res.status, fmt::format("HTTP status {}", res.status));
      }
      (void)req;
    });
  });
  // Before any body byte is read (server.h).
  const std::regex submission_route(kSubmissionRoute);
  http_->set_pre_routing_handler([submission_route](const httplib::Request& req,
                                                    httplib::Response& res) {
    HeadersReceived();
    bool handled = true;
    Guarded(res, [&] {
      CheckRequestTarget(req.path, req.params);
      const std::string encoding = req.get_header_value("Content-Encoding");
      if (req.has_header("Content-Encoding") && encoding != "identity") {
        throw Refused(415, fmt::format("Content-Encoding '{}' is not accepted: send the archive "
                                       "as it is (a .tar.gz is fine)",
                                       Printable(encoding, 100)));
      }
      const bool has_body =
          req.has_header("Transfer-Encoding") ||
          (req.has_header("Content-Length") && req.get_header_value("Content-Length") != "0");
      if (req.method == "POST" && std::regex_match(req.path, submission_route)) {
        // An upload may be refused before its body is read: never reuse the connection.
        CloseAfterResponse(req);
        handled = false;
        return;
      }
      if (req.method != "GET" && req.method != "HEAD") {
        throw Refused(req.method == "POST" ? 404 : 405,
                      fmt::format("{} is not served here", Printable(req.method, 20)));
      }
      if (has_body) throw Refused(400, "a GET request has no body");
      handled = false;
    });
    if (handled) CloseAfterResponse(req);
    return handled ? httplib::Server::HandlerResponse::Handled
                   : httplib::Server::HandlerResponse::Unhandled;
  });
  // Answers "Expect: 100-continue" with the refusal when the token or the length is wrong, so
  // such a client never sends the body.
  http_->set_expect_100_continue_handler(
      [this](const httplib::Request& req, httplib::Response& res) {
        int status = 100;
        Guarded(res, [&] {
          if (!store_.Authenticate(BearerToken(req))) {
            res.set_header("WWW-Authenticate", "Bearer");
            throw Refused(401, "a valid token is required: Authorization: Bearer TOKEN");
          }
          if (req.has_header("Content-Length") && DeclaredLength(req) > options_.max_body) {
            throw Refused(413, "the request body exceeds the server's limit");
          }
        });
        if (res.status >= 400) {
          status = res.status;
          CloseAfterResponse(req);
        }
        return status;
      });
  SetupApiRoutes();
  SetupPageRoutes();
}

Server::~Server() { Stop(); }

Server::RootLock::~RootLock() {
  if (fd >= 0) close(fd);  // releases the flock
}

void Server::SetupApiRoutes() {
  httplib::Server& http = *http_;
  http.Get("/api/datasets", [this](const httplib::Request&, httplib::Response& res) {
    Guarded(res, [&] { SendJson(res, 200, DatasetListJson(store_)); });
  });
  http.Get(R"(/api/datasets/([^/]+))", [this](const httplib::Request& req, httplib::Response& res) {
    Guarded(res, [&] {
      const auto json = DatasetJson(store_, req.matches[1]);
      json ? SendJson(res, 200, *json) : SendError(res, 404, "no such dataset");
    });
  });
  http.Get(R"(/api/datasets/([^/]+)/leaderboard)",
           [this](const httplib::Request& req, httplib::Response& res) {
             Guarded(res, [&] {
               LeaderboardOptions options;
               options.all_submissions = req.get_param_value("all") == "1";
               const auto json = LeaderboardJson(store_, req.matches[1], options);
               json ? SendJson(res, 200, *json) : SendError(res, 404, "no such dataset");
             });
           });
  // A published file: looked up by (dataset, file name) in the database only.
  http.Get(R"(/api/datasets/([^/]+)/([^/]+))", [this](const httplib::Request& req,
                                                      httplib::Response& res) {
    Guarded(res, [&] {
      const auto dataset = store_.FindDataset(req.matches[1]);
      const auto file = dataset ? store_.FindFile(dataset->id, req.matches[2]) : std::nullopt;
      if (!file) return SendError(res, 404, "no such file");
      SendFile(res, store_.root() / file->path, file->mime);
    });
  });
  http.Post(kSubmissionRoute, [this](const httplib::Request& req, httplib::Response& res,
                                     const httplib::ContentReader& content_reader) {
    Guarded(res, [&] { ReceiveSubmission(req, res, content_reader); });
  });
  http.Get(R"(/api/submissions/([^/]+))",
           [this](const httplib::Request& req, httplib::Response& res) {
             Guarded(res, [&] {
               const auto viewer = store_.Authenticate(BearerToken(req));
               const auto json = SubmissionJson(store_, req.matches[1], viewer);
               json ? SendJson(res, 200, *json) : SendError(res, 404, "no such submission");
             });
           });
  http.Get("/api/participants/me/submissions", [this](const httplib::Request& req,
                                                      httplib::Response& res) {
    Guarded(res, [&] {
      const auto participant = store_.Authenticate(BearerToken(req));
      if (!participant) {
        res.set_header("WWW-Authenticate", "Bearer");
        throw Refused(401, "a valid token is required: Authorization: Bearer TOKEN");
      }
      SendJson(res, 200,
               ParticipantSubmissionsJson(store_, *participant, submissions_.Quota(*participant)));
    });
  });
}

void Server::ReceiveSubmission(const httplib::Request& req, httplib::Response& res,
                               const httplib::ContentReader& content_reader) {
  const auto participant = store_.Authenticate(BearerToken(req));
  if (!participant) {
    res.set_header("WWW-Authenticate", "Bearer");
    throw Refused(401, "a valid token is required: Authorization: Bearer TOKEN");
  }
  const bool multipart = req.is_multipart_form_data();
  if (req.get_header_value("Content-Type") == "application/x-www-form-urlencoded") {
    throw Refused(415,
                  "send the archive as Content-Type: application/x-tar or application/zip "
                  "(or as multipart field 'archive'), not as a form");
  }
  if (req.has_header("Content-Length") && DeclaredLength(req) > options_.max_body) {
    throw Refused(413, "the request body exceeds the server's limit");
  }
  // The multipart parser buffers a part's headers: its input must be bounded by a length.
  if (multipart && !req.has_header("Content-Length")) {
    throw Refused(411, "a multipart upload must declare its Content-Length");
  }
  const std::string dataset = req.matches[1];
  Submissions::Upload upload = submissions_.Begin(*participant, dataset);
  const int fd =
      open(upload.archive().c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
  REPHOTO_CHECK(fd >= 0, "cannot create the upload file");
  struct Closer {
    ~Closer() { close(fd); }
    int fd;
  } closer{fd};
  size_t received = 0;
  bool too_large = false, write_failed = false;
  const auto count = [&](size_t n) {
    received += n;
    too_large = received > options_.max_body;
    return !too_large;
  };
  const auto write_archive = [&](const char* data, size_t n) {
    while (n > 0) {
      const ssize_t written = ::write(fd, data, n);
      if (written <= 0) {
        write_failed = true;
        return false;
      }
      data += written;
      n -= static_cast<size_t>(written);
    }
    return true;
  };
  std::string method = req.get_param_value("method");
  std::string description = req.get_param_value("description");
  bool ok = false;
  if (multipart) {
    std::string field;
    int archives = 0;
    ok = content_reader(
        [&](const httplib::MultipartFormData& part) {
          field = part.name;
          if (field == "archive") ++archives;
          if (field == "method") method.clear();
          if (field == "description") description.clear();
          return archives <= 1;
        },
        [&](const char* data, size_t n) {
          if (!count(n)) return false;
          if (field == "archive") return write_archive(data, n);
          std::string* text = field == "method"        ? &method
                              : field == "description" ? &description
                                                       : nullptr;
          // Kept up to 10001 bytes: longer is refused by Finish (the limit is 10000).
          if (text) text->append(data, std::min(n, 10001 - std::min<size_t>(text->size(), 10001)));
          return true;
        });
    if (ok && archives != 1) throw Refused(400, "multipart field 'archive' missing or repeated");
  } else {
    ok = content_reader(
        [&](const char* data, size_t n) { return count(n) && write_archive(data, n); });
  }
  if (too_large) throw Refused(413, "the request body exceeds the server's limit");
  if (RequestExpired()) {
    throw Refused(408,
                  fmt::format("the request did not arrive within {} s", options_.request_timeout));
  }
  REPHOTO_CHECK(!write_failed, "cannot write the upload to disk");
  if (!ok) throw Refused(400, "the request body could not be read (cut short or malformed)");
  const std::string id =
      submissions_.Finish(*participant, dataset, std::move(upload), method, description);
  SendJson(res, 202,
           {{"id", id},
            {"status", "queued"},
            {"url", "/api/submissions/" + id},
            {"quota", submissions_.Quota(*participant)}});
}

void Server::SetupPageRoutes() {
  httplib::Server& http = *http_;
  http.Get("/", [this](const httplib::Request&, httplib::Response& res) {
    Guarded(res, [&] { SendHtml(res, DatasetListPage(store_)); });
  });
  http.Get(R"(/datasets/([^/]+))", [this](const httplib::Request& req, httplib::Response& res) {
    Guarded(res, [&] { SendHtml(res, DatasetPage(store_, req.matches[1])); });
  });
  http.Get(R"(/datasets/([^/]+)/leaderboard)",
           [this](const httplib::Request& req, httplib::Response& res) {
             Guarded(res, [&] { SendHtml(res, LeaderboardPage(store_, req.matches[1])); });
           });
  http.Get(R"(/submissions/([^/]+))", [this](const httplib::Request& req, httplib::Response& res) {
    Guarded(res, [&] { SendHtml(res, SubmissionPage(store_, req.matches[1])); });
  });
}

int Server::Bind() {
  const fs::path lock = store_.root() / ".rephoto-serve";
  lock_.fd = open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  REPHOTO_CHECK(lock_.fd >= 0, "{}: cannot open the server lock", lock.string());
  REPHOTO_CHECK(flock(lock_.fd, LOCK_EX | LOCK_NB) == 0,
                "{}: another rephoto serve is running on this folder", store_.root().string());
  if (options_.port == 0) {
    port_ = http_->bind_to_any_port(options_.host);
    REPHOTO_CHECK(port_ > 0, "cannot listen on {}:<any port>", options_.host);
  } else {
    errno = 0;
    const bool bound = http_->bind_to_port(options_.host, options_.port);
    const int error = errno;
    REPHOTO_CHECK(bound, "cannot listen on {}:{}: {}", options_.host, options_.port,
                  error == EADDRINUSE
                      ? fmt::format("port {} is in use (another server?)", options_.port)
                  : error != 0 ? std::string(std::strerror(error))
                               : std::string("bind failed"));
    port_ = options_.port;
  }
  static_cast<GuardedHttpServer&>(*http_).SetBacklog(1024);
  submissions_.Start();
  return port_;
}

void Server::Run() {
  {
    std::lock_guard lock(run_mutex_);
    if (stop_requested_) return;
    running_ = true;
  }
  http_->listen_after_bind();
  running_ = false;
}

void Server::Stop() {
  {
    std::lock_guard lock(run_mutex_);
    stop_requested_ = true;
    if (!running_) return;  // Run() has not started (and now will not) or has returned
  }
  // Run() may not be listening yet, and httplib's stop() does nothing until it is.
  while (running_ && !http_->is_running()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  http_->stop();
  while (running_) std::this_thread::sleep_for(std::chrono::milliseconds(1));
}

}  // namespace rephoto::service
