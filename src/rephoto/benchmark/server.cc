#include "rephoto/benchmark/server.h"

#include <fcntl.h>
#include <fmt/format.h>
#include <httplib.h>
#include <sys/file.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <memory>
#include <thread>

#include "rephoto/benchmark/api.h"
#include "rephoto/benchmark/pages.h"
#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"

namespace rephoto::benchmark {
namespace fs = std::filesystem;
namespace {

void SendJson(httplib::Response& res, int status, const nlohmann::json& json) {
  res.status = status;
  res.set_content(json.dump(2) + "\n", "application/json");
}

void SendError(httplib::Response& res, int status, const std::string& message) {
  SendJson(res, status, {{"error", message}});
}

void SendHtml(httplib::Response& res, const std::optional<std::string>& html) {
  if (!html) {
    res.status = 404;
    res.set_content(NotFoundPage(), "text/html; charset=utf-8");
    return;
  }
  res.set_content(*html, "text/html; charset=utf-8");
}

// Streams a file from disk in 64 KiB chunks (tar files may be large).
void SendFile(httplib::Response& res, const fs::path& path, const std::string& mime) {
  auto in = std::make_shared<std::ifstream>(path, std::ios::binary);
  if (!*in) {
    SendError(res, 500, "a published file cannot be read");
    return;
  }
  const size_t size = fs::file_size(path);
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

}  // namespace

Server::Server(const fs::path& root, const ServerOptions& options)
    : options_(options),
      store_(root),
      submissions_(store_, options.limits, options.scoring_workers),
      http_(std::make_unique<httplib::Server>()) {
  const int threads = std::max(1, options.http_threads);
  http_->new_task_queue = [threads] { return new httplib::ThreadPool(threads); };
  http_->set_payload_max_length(options.max_body);
  http_->set_read_timeout(60);
  // Without it a response written in two parts waits for the client's delayed ACK (~25 ms).
  http_->set_tcp_nodelay(true);
  http_->set_exception_handler(
      [](const httplib::Request&, httplib::Response& res, std::exception_ptr error) {
        std::string message = "internal error";
        try {
          std::rethrow_exception(error);
        } catch (const Refused& refused) {
          SendError(res, refused.status, refused.what());
          return;
        } catch (const std::exception& e) {
          LogWarning(fmt::format("request failed: {}", e.what()));
        } catch (...) {
        }
        SendError(res, 500, message);
      });
  http_->set_error_handler([](const httplib::Request& req, httplib::Response& res) {
    if (!res.body.empty()) return;
    if (res.status == 413 &&
        req.get_header_value("Content-Type") == "application/x-www-form-urlencoded") {
      // The HTTP library caps form bodies at 8 KiB (curl --data-binary's default type).
      SendError(res, 413,
                "send the archive as Content-Type: application/x-tar or application/zip "
                "(or as multipart field 'archive'), not as a form");
    } else if (res.status == 413) {
      SendError(res, 413, "the request body exceeds the server's limit");
    } else if (res.status == 404) {
      SendError(res, 404, "not found");
    } else {
      SendError(res, res.status, fmt::format("HTTP status {}", res.status));
    }
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
    SendJson(res, 200, DatasetListJson(store_));
  });
  http.Get(R"(/api/datasets/([^/]+))", [this](const httplib::Request& req, httplib::Response& res) {
    const auto json = DatasetJson(store_, req.matches[1]);
    json ? SendJson(res, 200, *json) : SendError(res, 404, "no such dataset");
  });
  http.Get(R"(/api/datasets/([^/]+)/leaderboard)",
           [this](const httplib::Request& req, httplib::Response& res) {
             const auto json = LeaderboardJson(store_, req.matches[1]);
             json ? SendJson(res, 200, *json) : SendError(res, 404, "no such dataset");
           });
  // A published file: looked up by (dataset, file name) in the database only.
  http.Get(R"(/api/datasets/([^/]+)/([^/]+))", [this](const httplib::Request& req,
                                                      httplib::Response& res) {
    const auto dataset = store_.FindDataset(req.matches[1]);
    const auto file = dataset ? store_.FindFile(dataset->id, req.matches[2]) : std::nullopt;
    if (!file) return SendError(res, 404, "no such file");
    SendFile(res, store_.root() / file->path, file->mime);
  });
  http.Post(R"(/api/datasets/([^/]+)/submissions)", [this](const httplib::Request& req,
                                                           httplib::Response& res) {
    const auto participant = store_.Authenticate(BearerToken(req));
    if (!participant) {
      res.set_header("WWW-Authenticate", "Bearer");
      return SendError(res, 401, "a valid token is required: Authorization: Bearer TOKEN");
    }
    std::string method = req.get_param_value("method");
    std::string description = req.get_param_value("description");
    std::string_view archive = req.body;
    if (req.is_multipart_form_data()) {
      if (!req.has_file("archive")) return SendError(res, 400, "multipart field 'archive' missing");
      archive = req.files.find("archive")->second.content;
      if (req.has_file("method")) method = req.get_file_value("method").content;
      if (req.has_file("description")) description = req.get_file_value("description").content;
    }
    const std::string id =
        submissions_.Submit(*participant, req.matches[1], archive, method, description);
    SendJson(res, 202, {{"id", id}, {"status", "queued"}, {"url", "/api/submissions/" + id}});
  });
  http.Get(R"(/api/submissions/([^/]+))",
           [this](const httplib::Request& req, httplib::Response& res) {
             const auto json = SubmissionJson(store_, req.matches[1]);
             json ? SendJson(res, 200, *json) : SendError(res, 404, "no such submission");
           });
  // Error images of a submission: (id, stem, metric) checked against the records.
  http.Get(R"(/api/submissions/([0-9a-f]{32})/errors/([^/]+)\.png)",
           [this](const httplib::Request& req, httplib::Response& res) {
             const auto path = ErrorImagePath(store_, req.matches[1], req.matches[2]);
             if (!path) return SendError(res, 404, "no such error image");
             SendFile(res, *path, "image/png");
           });
}

void Server::SetupPageRoutes() {
  httplib::Server& http = *http_;
  http.Get("/", [this](const httplib::Request&, httplib::Response& res) {
    SendHtml(res, DatasetListPage(store_));
  });
  http.Get(R"(/datasets/([^/]+))", [this](const httplib::Request& req, httplib::Response& res) {
    SendHtml(res, DatasetPage(store_, req.matches[1]));
  });
  http.Get(R"(/datasets/([^/]+)/leaderboard)",
           [this](const httplib::Request& req, httplib::Response& res) {
             SendHtml(res, LeaderboardPage(store_, req.matches[1]));
           });
  http.Get(R"(/submissions/([^/]+))", [this](const httplib::Request& req, httplib::Response& res) {
    SendHtml(res, SubmissionPage(store_, req.matches[1]));
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
    REPHOTO_CHECK(http_->bind_to_port(options_.host, options_.port), "cannot listen on {}:{}",
                  options_.host, options_.port);
    port_ = options_.port;
  }
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

}  // namespace rephoto::benchmark
