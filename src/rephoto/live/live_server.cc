#include "rephoto/live/live_server.h"

#include <httplib.h>
#include <sys/socket.h>

#include <cerrno>
#include <cstring>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"

namespace rephoto::live {
namespace fs = std::filesystem;

namespace {

void SendError(httplib::Response& res, int status, const std::string& message) {
  res.status = status;
  res.set_content(nlohmann::json({{"error", message}}).dump(), "application/json");
}

template <typename F>
void Guarded(httplib::Response& res, F&& f) {
  try {
    f();
  } catch (const std::exception& e) {
    SendError(res, 500, e.what());
  } catch (...) {
    SendError(res, 500, "internal error");
  }
}

}  // namespace

std::pair<std::string, int> ParseListen(const std::string& text) {
  const size_t colon = text.rfind(':');
  REPHOTO_CHECK_USAGE(colon != std::string::npos && colon > 0,
                      "--listen '{}': expected HOST:PORT, e.g. 127.0.0.1:8090", text);
  const std::string port = text.substr(colon + 1);
  REPHOTO_CHECK_USAGE(!port.empty() && port.size() <= 5 &&
                          port.find_first_not_of("0123456789") == std::string::npos &&
                          std::stoi(port) <= 65535,
                      "--listen '{}': the port must be a number 0-65535", text);
  return {text.substr(0, colon), std::stoi(port)};
}

LiveServer::LiveServer(const LiveSession& session, const fs::path& run)
    : session_(session), run_(run), http_(std::make_unique<httplib::Server>()) {
  http_->new_task_queue = [] { return new httplib::ThreadPool(8); };
  http_->set_tcp_nodelay(true);
  http_->set_read_timeout(5, 0);
  http_->set_keep_alive_timeout(5);
  http_->set_payload_max_length(0);
  http_->set_socket_options([](socket_t sock) {
    int yes = 1;
    setsockopt(sock, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  });
  http_->set_exception_handler(
      [](const httplib::Request&, httplib::Response& res, std::exception_ptr error) {
        Guarded(res, [&] { std::rethrow_exception(error); });
      });
  http_->set_error_handler([](const httplib::Request&, httplib::Response& res) {
    Guarded(res, [&] {
      if (res.body.empty()) SendError(res, res.status, fmt::format("HTTP status {}", res.status));
    });
  });
  http_->Get("/", [](const httplib::Request&, httplib::Response& res) {
    Guarded(res, [&] {
      res.set_header("Cache-Control", "no-store");
      res.set_content(LivePageHtml(), "text/html; charset=utf-8");
    });
  });
  http_->Get("/api/live", [this](const httplib::Request&, httplib::Response& res) {
    Guarded(res, [&] {
      res.set_header("Cache-Control", "no-store");
      nlohmann::json api = session_.Api();
      // Whether RUN holds a closed-loop plot (/files/closed_loop.svg), for the page.
      std::error_code ec;
      api["closed_loop_plot"] = fs::is_regular_file(run_ / "closed_loop.svg", ec);
      res.set_content(api.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace),
                      "application/json");
    });
  });
  http_->Get(R"(/files/suggestions/(transforms\.json|sparse/cameras\.txt|sparse/images\.txt|sparse/points3D\.txt))",
             [this](const httplib::Request& req, httplib::Response& res) {
               Guarded(res, [&] {
                 const std::string which = req.matches[1];
                 const fs::path path = run_ / "suggestions" / which;
                 std::error_code ec;
                 if (!fs::is_regular_file(path, ec)) return SendError(res, 404, "not found");
                 res.set_header("Cache-Control", "no-store");
                 res.set_content(ReadFileToString(path),
                                 which.ends_with(".json") ? "application/json" : "text/plain");
               });
             });
  // The closed-loop plot that `rephoto live-experiment` leaves in each of its runs (a fixed
  // name inside RUN; 404 for other runs). Served with a CSP that runs no script in it.
  http_->Get("/files/closed_loop.svg", [this](const httplib::Request&, httplib::Response& res) {
    Guarded(res, [&] {
      const fs::path path = run_ / "closed_loop.svg";
      std::error_code ec;
      if (!fs::is_regular_file(path, ec)) return SendError(res, 404, "not found");
      res.set_header("Cache-Control", "no-store");
      res.set_header("Content-Security-Policy", "default-src 'none'; style-src 'unsafe-inline'");
      res.set_content(ReadFileToString(path), "image/svg+xml");
    });
  });
  http_->Get(R"(/files/(photo|prediction|error|suggestion)/([^/]+))",
             [this](const httplib::Request& req, httplib::Response& res) {
               Guarded(res, [&] {
                 const std::optional<fs::path> path = session_.FilePath(req.matches[1], req.matches[2]);
                 std::error_code ec;
                 if (!path || !fs::is_regular_file(*path, ec)) return SendError(res, 404, "not found");
                 res.set_header("Cache-Control", "no-store");
                 res.set_content(ReadFileToString(*path), "image/png");
               });
             });
}

LiveServer::~LiveServer() { Stop(); }

int LiveServer::Bind(const std::string& host, int port) {
  if (port == 0) {
    const int p = http_->bind_to_any_port(host);
    REPHOTO_CHECK(p > 0, "cannot listen on {}: {}", host, std::strerror(errno));
    return p;
  }
  const bool bound = http_->bind_to_port(host, port);
  const int error = errno;
  REPHOTO_CHECK(bound, "cannot listen on {}:{}: {}", host, port, std::strerror(error));
  return port;
}

void LiveServer::Run() { http_->listen_after_bind(); }

void LiveServer::Stop() {
  if (http_) http_->stop();
}

}  // namespace rephoto::live
