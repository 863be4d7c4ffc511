// The fixture of the server tests (server_test.cc, hostile_test.cc): an in-process Server on a
// free port of 127.0.0.1 over a root with the tiny dataset and three participants (alice, bob,
// and mallory, revoked), and raw-socket helpers. Test-only; one thread.
#pragma once

#include <gtest/gtest.h>
#include <poll.h>

#include <chrono>
#include <functional>
#include <thread>

#include "rephoto/service/api.h"
#include "rephoto/service/dataset.h"
#include "rephoto/service/server.h"
#include "rephoto/service/test_fixture.h"
#include "rephoto/core/file.h"
#include "rephoto/testing/testing.h"

// After Eigen (through the rephoto headers): <resolv.h>, which httplib includes, defines a
// macro `_res` that Eigen uses as a parameter name.
#include <arpa/inet.h>
#include <httplib.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

namespace rephoto::service::testing {
namespace fs = std::filesystem;

// A TCP connection to 127.0.0.1:port from the local address `from` (any 127.x.y.z), or -1.
inline int Connect(int port, const char* from = "127.0.0.1") {
  const int fd = socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in local{};
  local.sin_family = AF_INET;
  inet_pton(AF_INET, from, &local.sin_addr);
  if (bind(fd, reinterpret_cast<sockaddr*>(&local), sizeof(local)) != 0) {
    close(fd);
    return -1;
  }
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(port));
  inet_pton(AF_INET, "127.0.0.1", &address.sin_addr);
  if (connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)) != 0) {
    close(fd);
    return -1;
  }
  return fd;
}

// Sends `request` verbatim (no client-side normalisation of the path) and returns the whole
// response.
// Sends `head`, then the pieces `next(bytes sent so far)` returns (until it returns ""), and
// stops sending as soon as the server answers or closes; returns the response (read until it
// is complete or the server closes, at most 10 s) and how many body bytes were sent.
struct Streamed {
  std::string response;
  size_t sent = 0;
};
// Whether `response` holds a whole response with a Content-Length.
inline bool ResponseComplete(const std::string& response) {
  const size_t end = response.find("\r\n\r\n");
  if (end == std::string::npos) return false;
  std::string head = response.substr(0, end);
  for (char& c : head) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  const size_t at = head.find("\r\ncontent-length: ");
  if (at == std::string::npos) return false;
  const size_t length = std::stoul(head.substr(at + 18));
  return response.size() >= end + 4 + length;
}

inline Streamed SendStreaming(int port, const std::string& head,
                              const std::function<std::string(size_t)>& next) {
  Streamed result;
  const int fd = Connect(port);
  EXPECT_GE(fd, 0);
  if (fd < 0) return result;
  EXPECT_EQ(send(fd, head.data(), head.size(), MSG_NOSIGNAL), static_cast<ssize_t>(head.size()));
  for (;;) {
    pollfd readable{fd, POLLIN, 0};
    if (poll(&readable, 1, 0) > 0) break;  // answered (or closed)
    const std::string piece = next(result.sent);
    if (piece.empty()) break;
    const ssize_t n = send(fd, piece.data(), piece.size(), MSG_NOSIGNAL);
    if (n <= 0) break;
    result.sent += static_cast<size_t>(n);
  }
  const auto start = std::chrono::steady_clock::now();
  char buffer[65536];
  while (std::chrono::steady_clock::now() - start < std::chrono::seconds(10)) {
    pollfd readable{fd, POLLIN, 0};
    if (poll(&readable, 1, 1000) <= 0) continue;
    const ssize_t n = recv(fd, buffer, sizeof(buffer), 0);
    if (n <= 0) break;
    result.response.append(buffer, static_cast<size_t>(n));
    if (ResponseComplete(result.response)) break;  // a kept-alive connection stays open
  }
  close(fd);
  return result;
}

inline int StatusOf(const std::string& response) {
  if (response.rfind("HTTP/1.1 ", 0) != 0 || response.size() < 12) return 0;
  return std::stoi(response.substr(9, 3));
}

inline std::string Chunk(const std::string& data) {
  return fmt::format("{:x}\r\n", data.size()) + data + "\r\n";
}

inline std::string RawHttp(int port, const std::string& request) {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<uint16_t>(port));
  inet_pton(AF_INET, "127.0.0.1", &address.sin_addr);
  EXPECT_EQ(connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address)), 0);
  EXPECT_EQ(write(fd, request.data(), request.size()), static_cast<ssize_t>(request.size()));
  std::string response;
  char buffer[65536];
  for (ssize_t n; (n = read(fd, buffer, sizeof(buffer))) > 0;) response.append(buffer, n);
  close(fd);
  return response;
}

class ServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    rng_ = rephoto::testing::MakeRng();
    base_ = rephoto::testing::MakeTempDir();
    const fs::path& base = base_;
    root_ = base / "root";
    fs::create_directories(root_);
    MakeTinyScene(base / "scene", 6, 64, 48, rng_);
    {
      Store store(root_);
      AddTinyDataset(store, base / "scene", "tiny");
      alice_ = store.AddParticipant("alice");
      bob_ = store.AddParticipant("bob");
      revoked_ = store.AddParticipant("mallory");
      store.RevokeParticipant("mallory");
    }
    StartServer(DefaultOptions());
  }
  void TearDown() override { StopServer(); }
  static ServerOptions DefaultOptions() {
    ServerOptions options;
    options.host = "127.0.0.1";
    options.port = 0;
    options.http_threads = 4;
    options.max_body = 300000;
    options.limits.archive = {.max_bytes = 200000, .max_files = 4};
    options.limits.max_per_window = 30;
    options.access_log = "";
    return options;
  }
  void StartServer(const ServerOptions& options) {
    server_ = std::make_unique<Server>(root_, options);
    port_ = server_->Bind();
    thread_ = std::thread([this] { server_->Run(); });
    client_ = std::make_unique<httplib::Client>("127.0.0.1", port_);
    client_->set_read_timeout(60);
  }
  // Adds another dataset of the same tiny scene (while the server runs: safe, see store.h).
  void AddTinyDatasetTo(const std::string& name, const std::string& ranking,
                        double public_fraction = 1) {
    Store store(root_);
    AddTinyDataset(store, base_ / "scene", name, ranking, public_fraction);
  }
  void StopServer() {
    if (!server_) return;
    server_->Stop();
    thread_.join();
    server_.reset();
  }
  httplib::Result Submit(const std::string& token, const std::string& archive,
                         const std::string& method = "m") {
    httplib::Headers headers;
    if (!token.empty()) headers.emplace("Authorization", "Bearer " + token);
    return client_->Post(("/api/datasets/" + dataset_ + "/submissions?method=" + method).c_str(),
                         headers, archive, "application/x-tar");
  }
  // The id of an accepted submission (fails the test otherwise).
  std::string SubmitOk(const std::string& token, const std::string& archive,
                       const std::string& method = "m") {
    const auto res = Submit(token, archive, method);
    EXPECT_TRUE(res && res->status == 202) << (res ? res->body : "no response");
    return res && res->status == 202 ? nlohmann::json::parse(res->body)["id"].get<std::string>()
                                     : "";
  }
  nlohmann::json Json(const std::string& path, const std::string& token = "") {
    httplib::Headers headers;
    if (!token.empty()) headers.emplace("Authorization", "Bearer " + token);
    const auto res = client_->Get(path.c_str(), headers);
    EXPECT_TRUE(res);
    if (!res) return nullptr;
    EXPECT_EQ(res->status, 200) << path;
    return nlohmann::json::parse(res->body);
  }
  std::vector<std::string> SecretPhotos() const {
    std::vector<std::string> photos;
    for (const auto& entry : fs::directory_iterator(SecretPhotoFolder(root_, "tiny"))) {
      photos.push_back(ReadFileToString(entry.path()));
    }
    return photos;
  }

  std::mt19937_64 rng_;
  fs::path base_, root_;
  std::string alice_, bob_, revoked_;
  std::unique_ptr<Server> server_;
  std::thread thread_;
  int port_ = 0;
  std::unique_ptr<httplib::Client> client_;
  std::string dataset_ = "tiny";
};

}  // namespace rephoto::service::testing
