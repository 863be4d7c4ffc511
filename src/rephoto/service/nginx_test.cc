// The shipped nginx front-end (src/rephoto/service/nginx.conf) started by the test: Debian's
// nginx with TLS (a certificate the test makes with openssl) in front of an in-process server,
// and issue 27's hostile requests sent through it (over TLS): they get the same refusals,
// secrets and paths stay in, slow clients do not stop the service, and an honest submission is
// scored. Skipped when /usr/sbin/nginx is missing (scripts/install-deps.sh installs it).
#include <openssl/err.h>
#include <openssl/ssl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <atomic>
#include <chrono>
#include <fstream>
#include <regex>

#include "rephoto/io/image_io.h"
// Last: it includes httplib (see there).
#include "rephoto/service/server_fixture.h"

extern char** environ;

namespace rephoto::service {
namespace {
namespace fs = std::filesystem;
using testing::ArchiveFormat;
using testing::Chunk;
using testing::Connect;
using testing::MakeArchive;
using testing::ServerTest;
using testing::StatusOf;
using Clock = std::chrono::steady_clock;

const char* const kNginx = "/usr/sbin/nginx";

// A free TCP port of 127.0.0.1 (bound, read, released).
int FreePort() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  inet_pton(AF_INET, "127.0.0.1", &address.sin_addr);
  bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof(address));
  socklen_t length = sizeof(address);
  getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length);
  close(fd);
  return ntohs(address.sin_port);
}

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  for (size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size())) {
    text.replace(at, from.size(), to);
  }
  return text;
}

// Sends `head` and the pieces `next` gives over TLS until the server answers; returns the
// response (read until the server closes, at most 10 s).
std::string TlsRequest(int port, const std::string& head,
                       const std::function<std::string(size_t)>& next) {
  std::unique_ptr<SSL_CTX, void (*)(SSL_CTX*)> context(SSL_CTX_new(TLS_client_method()),
                                                       SSL_CTX_free);
  // TLS 1.2: a TLS 1.3 server sends session tickets after the handshake, which would make the
  // socket readable before any response (the loop below stops sending when it is).
  SSL_CTX_set_max_proto_version(context.get(), TLS1_2_VERSION);
  const int fd = Connect(port);
  if (fd < 0) return "";
  timeval timeout{10, 0};  // bounds every read below
  setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof(timeout));
  std::unique_ptr<SSL, void (*)(SSL*)> ssl(SSL_new(context.get()), SSL_free);
  SSL_set_fd(ssl.get(), fd);
  std::string response;
  if (SSL_connect(ssl.get()) == 1) {
    SSL_write(ssl.get(), head.data(), static_cast<int>(head.size()));
    size_t sent = 0;
    for (;;) {
      pollfd readable{fd, POLLIN, 0};
      if (SSL_pending(ssl.get()) > 0 || poll(&readable, 1, 5) > 0) break;
      const std::string piece = next(sent);
      if (piece.empty()) break;
      if (SSL_write(ssl.get(), piece.data(), static_cast<int>(piece.size())) <= 0) break;
      sent += piece.size();
    }
    const Clock::time_point start = Clock::now();
    char buffer[16384];
    while (Clock::now() - start < std::chrono::seconds(10)) {
      const int n = SSL_read(ssl.get(), buffer, sizeof(buffer));
      if (n <= 0) break;
      response.append(buffer, static_cast<size_t>(n));
    }
  }
  close(fd);
  return response;
}

class NginxTest : public ServerTest {
 protected:
  void SetUp() override {
    if (!fs::exists(kNginx)) GTEST_SKIP() << "no " << kNginx;
    ServerTest::SetUp();
    StopServer();
    ServerOptions options = DefaultOptions();
    options.max_connections_per_address = 64;  // every connection comes from nginx
    StartServer(options);
    const fs::path prefix = base_ / "nginx";
    fs::create_directories(prefix);
    const std::string cert = (prefix / "cert.pem").string(), key = (prefix / "key.pem").string();
    ASSERT_EQ(std::system(("openssl req -x509 -newkey rsa:2048 -nodes -days 1 -subj /CN=127.0.0.1 "
                           "-keyout '" +
                           key + "' -out '" + cert + "' 2>/dev/null")
                              .c_str()),
              0);
    nginx_port_ = FreePort();
    std::string config = ReadFileToString(REPHOTO_NGINX_CONF);
    config = Replace(config, "@PREFIX@", prefix.string());
    config = Replace(config, "@LISTEN@", "127.0.0.1:" + std::to_string(nginx_port_));
    config = Replace(config, "@CERT@", cert);
    config = Replace(config, "@KEY@", key);
    config = Replace(config, "@UPSTREAM@", "127.0.0.1:" + std::to_string(port_));
    config = Replace(config, "@MAX_BODY@", "300000");
    ASSERT_EQ(config.find('@'), std::string::npos);
    WriteTextFileAtomically(prefix / "nginx.conf", config);
    std::vector<std::string> args = {
        kNginx, "-p", prefix.string(), "-c", (prefix / "nginx.conf").string(), "-g", "daemon off;"};
    std::vector<char*> argv;
    for (std::string& arg : args) argv.push_back(arg.data());
    argv.push_back(nullptr);
    ASSERT_EQ(posix_spawn(&nginx_pid_, kNginx, nullptr, nullptr, argv.data(), environ), 0);
    for (int i = 0; i < 200; ++i) {
      const int fd = Connect(nginx_port_);
      if (fd >= 0) {
        close(fd);
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(25));
    }
    https_ = std::make_unique<httplib::SSLClient>("127.0.0.1", nginx_port_);
    https_->enable_server_certificate_verification(false);
    https_->set_read_timeout(30);
  }
  void TearDown() override {
    if (nginx_pid_ > 0) {
      kill(nginx_pid_, SIGTERM);
      int status = 0;
      waitpid(nginx_pid_, &status, 0);
    }
    if (server_) ServerTest::TearDown();
  }
  httplib::Result SubmitTls(const std::string& token, const std::string& archive,
                            const std::string& method = "m") {
    return https_->Post(("/api/datasets/tiny/submissions?method=" + method).c_str(),
                        {{"Authorization", "Bearer " + token}}, archive, "application/x-tar");
  }

  std::string NginxLog() const {
    const fs::path log = base_ / "nginx" / "error.log";
    return fs::exists(log) ? "\nnginx error.log:\n" + ReadFileToString(log) : "";
  }

  int nginx_port_ = 0;
  pid_t nginx_pid_ = 0;
  std::unique_ptr<httplib::SSLClient> https_;
};

TEST_F(NginxTest, HostileRequestsThroughNginxGetTheSameRefusals) {
  // An honest submission is scored; its per-photo numbers only with the token.
  const auto honest = SubmitTls(alice_, testing::RendersFromPhotos(root_, "tiny", 0.05, rng_));
  ASSERT_TRUE(honest);
  ASSERT_EQ(honest->status, 202) << honest->body;
  const std::string id = nlohmann::json::parse(honest->body)["id"];
  ASSERT_TRUE(server_->submissions().WaitIdle(60));
  const auto public_json = https_->Get(("/api/submissions/" + id).c_str());
  ASSERT_TRUE(public_json && public_json->status == 200);
  EXPECT_EQ(nlohmann::json::parse(public_json->body)["status"], "done");
  EXPECT_FALSE(nlohmann::json::parse(public_json->body).contains("images"));
  EXPECT_EQ(https_->Get(("/api/submissions/" + id + "/errors/00.psnr.png").c_str())->status, 404);
  const std::string absolute_root = fs::absolute(root_).string();
  for (const std::string& path :
       std::vector<std::string>{"/", "/api/datasets/tiny/leaderboard", "/datasets/tiny/leaderboard",
                                "/api/submissions/" + id, "/submissions/" + id}) {
    const auto res = https_->Get(path.c_str());
    ASSERT_TRUE(res && res->status == 200) << path;
    EXPECT_EQ(res->body.find(absolute_root), std::string::npos) << path;
  }
  // Observations 3 and 4: refused with 400, and everything still answers.
  const std::string png = ReadFileToString(SecretPhotoFolder(root_, "tiny") / "00.png");
  EXPECT_EQ(SubmitTls(alice_, MakeArchive({{"\xff\xfe.png", png}}, ArchiveFormat::kTar))->status,
            400);
  EXPECT_EQ(
      SubmitTls(alice_, MakeArchive({{"00.png", png}}, ArchiveFormat::kTar), "bad%FFname")->status,
      400);
  EXPECT_EQ(
      SubmitTls(alice_, MakeArchive({{"00.png", png}}, ArchiveFormat::kTar), "%00nul")->status,
      400);
  EXPECT_EQ(https_->Get("/api/datasets/tiny/leaderboard")->status, 200);
  // Secret photos under other spellings.
  for (const char* path : {"/secret/tiny/photos/00.png", "/api/datasets/tiny/..%2f..%2fsecret",
                           "/api/datasets/tiny/%2e%2e/%2e%2e/secret/tiny/photos/00.png"}) {
    const auto res = https_->Get(path);
    ASSERT_TRUE(res);
    EXPECT_TRUE(res->status == 404 || res->status == 400) << path << " " << res->status;
    EXPECT_EQ(res->body.find(png.substr(64, 64)), std::string::npos);
  }
  // Observation 2: bodies over the limit, chunked or declared, and a Content-Encoding.
  const std::string target =
      "POST /api/datasets/tiny/submissions?method=m HTTP/1.1\r\nHost: x\r\nConnection: close\r\n";
  const std::string auth = "Authorization: Bearer " + alice_ + "\r\n";
  const std::string type = "Content-Type: application/x-tar\r\n";
  const std::string piece(64 << 10, 'x');
  std::string response =
      TlsRequest(nginx_port_, target + auth + type + "Transfer-Encoding: chunked\r\n\r\n",
                 [&](size_t sent) { return sent < (size_t{20} << 20) ? Chunk(piece) : ""; });
  EXPECT_EQ(StatusOf(response), 413) << response.size() << response.substr(0, 100) << NginxLog();
  // A declared length: nginx answers at the headers.
  response = TlsRequest(nginx_port_, target + auth + type + "Content-Length: 100000000\r\n\r\n",
                        [&](size_t) { return std::string(); });
  EXPECT_EQ(StatusOf(response), 413) << response.substr(0, 100);
  const std::string small = MakeArchive({{"00.png", png}}, ArchiveFormat::kTar);
  response = TlsRequest(nginx_port_,
                        target + auth + type + "Content-Encoding: gzip\r\n" +
                            fmt::format("Content-Length: {}\r\n\r\n", small.size()),
                        [&](size_t sent) { return sent == 0 ? small : ""; });
  EXPECT_EQ(StatusOf(response), 415) << response.substr(0, 300) << NginxLog();
  // Without a token (a body within nginx's limit: a larger one is nginx's 413 first).
  response = TlsRequest(nginx_port_, target + type + "Transfer-Encoding: chunked\r\n\r\n",
                        [&](size_t sent) { return sent == 0 ? Chunk(small) + "0\r\n\r\n" : ""; });
  EXPECT_EQ(StatusOf(response), 401) << response.substr(0, 100);
  EXPECT_TRUE(
      !fs::exists(root_ / "submissions") ||
      std::distance(fs::directory_iterator(root_ / "submissions"), fs::directory_iterator()) == 1);
}

// Observation 5 through nginx: 8 connections trickling a byte per second (before the TLS
// handshake even completes) do not delay a client.
TEST_F(NginxTest, SlowClientsThroughNginxDoNotStopTheService) {
  std::atomic<bool> stop = false;
  std::vector<std::thread> slow;
  for (int i = 0; i < 8; ++i) {
    slow.emplace_back([&] {
      const int fd = Connect(nginx_port_, "127.0.0.2");
      if (fd < 0) return;
      for (int k = 0; k < 4 && !stop; ++k) {
        if (send(fd, "\x16", 1, MSG_NOSIGNAL) != 1) break;
        std::this_thread::sleep_for(std::chrono::seconds(1));
      }
      close(fd);
    });
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  for (int probe = 0; probe < 6; ++probe) {
    httplib::SSLClient client("127.0.0.1", nginx_port_);
    client.enable_server_certificate_verification(false);
    client.set_connection_timeout(2);
    client.set_read_timeout(2);
    const Clock::time_point start = Clock::now();
    const auto res = client.Get("/api/datasets");
    const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
    EXPECT_TRUE(res && res->status == 200) << probe;
    EXPECT_LT(seconds, 1.0) << probe;
    std::this_thread::sleep_for(std::chrono::milliseconds(400));
  }
  stop = true;
  for (std::thread& thread : slow) thread.join();
}

}  // namespace
}  // namespace rephoto::service
