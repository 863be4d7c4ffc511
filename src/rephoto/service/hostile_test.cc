// The service against a hostile participant and anonymous clients (issue 27): one test per
// observation of the issue, each of which failed on the server before it, on a real server on
// 127.0.0.1 (in process, and a `rephoto serve` process for memory), with bounded loops.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <fstream>
#include <functional>
#include <regex>

#include "rephoto/service/server.h"
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
using testing::SendStreaming;
using testing::ServerTest;
using testing::StatusOf;
using testing::Streamed;
using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// A tar of the dataset's test images rendered as flat grey (128, 128, 128, 255).
std::string FlatGreyRenders(const fs::path& work) {
  Image grey(64, 48, 4, 128.0f / 255.0f);
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 64; ++x) grey.at(x, y, 3) = 1.0f;
  }
  io::WritePng(work / "grey.png", grey);
  const std::string png = ReadFileToString(work / "grey.png");
  return MakeArchive({{"00.png", png}, {"03.png", png}}, ArchiveFormat::kTar);
}

// Every response of the public API and pages about the dataset and these submissions, and the
// same with `token`.
std::vector<std::string> EveryResponse(httplib::Client& client, const std::vector<std::string>& ids,
                                       const std::string& token) {
  std::vector<std::string> paths = {"/",
                                    "/datasets/tiny",
                                    "/datasets/tiny/leaderboard",
                                    "/api/datasets",
                                    "/api/datasets/tiny",
                                    "/api/datasets/tiny/leaderboard",
                                    "/api/datasets/tiny/leaderboard?all=1"};
  for (const std::string& id : ids) {
    paths.push_back("/api/submissions/" + id);
    paths.push_back("/submissions/" + id);
  }
  std::vector<std::string> bodies;
  for (const std::string& path : paths) {
    for (const std::string& with : {std::string(), token}) {
      httplib::Headers headers;
      if (!with.empty()) headers.emplace("Authorization", "Bearer " + with);
      const auto res = client.Get(path.c_str(), headers);
      EXPECT_TRUE(res && res->status == 200) << path;
      if (res) bodies.push_back(res->body);
    }
  }
  return bodies;
}

// Observation 1: the psnr error image of a flat grey render was (photo - 0.5)^2.
TEST_F(ServerTest, Issue27Obs1_NothingDerivedFromASecretPhotoLeavesTheServer) {
  const std::string id = SubmitOk(alice_, FlatGreyRenders(base_));
  ASSERT_TRUE(server_->submissions().WaitIdle(60));
  EXPECT_EQ(Json("/api/submissions/" + id)["status"], "done");
  // No error image is made at all, so none can be served.
  EXPECT_FALSE(fs::exists(SubmissionRunFolder(root_, id) / "errors"));
  for (const char* stem : {"00", "03"}) {
    for (const char* metric : {"1-ncc", "cb+cr", "psnr"}) {
      const auto res =
          client_->Get(fmt::format("/api/submissions/{}/errors/{}.{}.png", id, stem, metric));
      ASSERT_TRUE(res);
      EXPECT_EQ(res->status, 404) << stem << "." << metric;
    }
  }
  // Per-photo numbers: alice's own, with her token; nobody else's.
  EXPECT_FALSE(Json("/api/submissions/" + id).contains("images"));
  EXPECT_FALSE(Json("/api/submissions/" + id, bob_).contains("images"));
  const nlohmann::json own = Json("/api/submissions/" + id, alice_);
  ASSERT_EQ(own["images"].size(), 2u);
  EXPECT_EQ(own["images"][0]["name"], "00");
  EXPECT_GT(JsonNumber(own["images"][0]["1-ncc"]), 0.5);  // flat: one side flat -> 1
  // No page has an image, no response a PNG, and no response (anyone's, with or without a
  // token) holds a 64-byte piece of a secret photo.
  const std::vector<std::string> photos = SecretPhotos();
  for (const std::string& body : EveryResponse(*client_, {id}, bob_)) {
    EXPECT_EQ(body.find("<img"), std::string::npos);
    EXPECT_EQ(body.find("\x89PNG"), std::string::npos);
    for (const std::string& photo : photos) {
      for (size_t offset = 64; offset + 64 <= photo.size(); offset += 64) {
        ASSERT_EQ(body.find(photo.substr(offset, 64)), std::string::npos);
      }
    }
  }
}

// Observation 2 (statuses; the memory bound is checked on a server process below): a body is
// refused at max_body whatever its framing, and before it is read without a valid token.
TEST_F(ServerTest, Issue27Obs2_BodiesAreRefusedAtTheLimitWhateverTheirFraming) {
  const std::string piece(64 << 10, 'x');
  const std::string target = "POST /api/datasets/tiny/submissions?method=m HTTP/1.1\r\n";
  const std::string auth = "Authorization: Bearer " + alice_ + "\r\n";
  const std::string type = "Content-Type: application/x-tar\r\n";
  const auto chunks = [&](size_t sent) {
    return sent < (size_t{20} << 20) ? Chunk(piece) : std::string();
  };
  const auto raw = [&](size_t sent) { return sent < (size_t{20} << 20) ? piece : std::string(); };
  // 20 MiB chunked, limit 300000 bytes: 413 once the limit is passed.
  Streamed r =
      SendStreaming(port_, target + auth + type + "Transfer-Encoding: chunked\r\n\r\n", chunks);
  EXPECT_EQ(StatusOf(r.response), 413) << r.response.substr(0, 200);
  EXPECT_LT(r.sent, size_t{10} << 20);
  // Without a Content-Length (the body ends when the client closes).
  r = SendStreaming(port_, target + auth + type + "Connection: close\r\n\r\n", raw);
  EXPECT_EQ(StatusOf(r.response), 413) << r.response.substr(0, 200);
  EXPECT_LT(r.sent, size_t{10} << 20);
  // Without a token: 401 before a byte of the body is read.
  r = SendStreaming(port_, target + type + "Transfer-Encoding: chunked\r\n\r\n", chunks);
  EXPECT_EQ(StatusOf(r.response), 401) << r.response.substr(0, 200);
  EXPECT_LT(r.sent, size_t{10} << 20);
  // Content-Encoding: never inflated, refused at the headers.
  r = SendStreaming(
      port_, target + auth + type + "Content-Encoding: gzip\r\nContent-Length: 2000000\r\n\r\n",
      raw);
  EXPECT_EQ(StatusOf(r.response), 415) << r.response.substr(0, 200);
  // A body where none belongs.
  r = SendStreaming(port_, "GET /api/datasets HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n",
                    chunks);
  EXPECT_EQ(StatusOf(r.response), 400) << r.response.substr(0, 200);
  r = SendStreaming(port_, "PUT /api/datasets HTTP/1.1\r\nContent-Length: 100000000\r\n\r\n", raw);
  EXPECT_EQ(StatusOf(r.response), 405) << r.response.substr(0, 200);
  // Nothing of them stays on disk; the server still serves.
  EXPECT_TRUE(!fs::exists(root_ / "submissions") || fs::is_empty(root_ / "submissions"));
  EXPECT_EQ(Json("/api/datasets").size(), 1u);
}

// Observation 3: `terminate called after throwing ... json type_error.316`.
TEST_F(ServerTest, Issue27Obs3_AMemberNamedWithInvalidUtf8IsRefusedAndTheServerLives) {
  const std::string png = ReadFileToString(SecretPhotoFolder(root_, "tiny") / "00.png");
  for (const ArchiveFormat format : {ArchiveFormat::kTar, ArchiveFormat::kZip}) {
    const auto res = Submit(alice_, MakeArchive({{"\xff\xfe.png", png}}, format));
    ASSERT_TRUE(res) << "the server died";
    EXPECT_EQ(res->status, 400) << res->body;
    EXPECT_NE(res->body.find("\\\\xff\\\\xfe.png"), std::string::npos) << res->body;
    EXPECT_TRUE(nlohmann::json::accept(res->body));
  }
  EXPECT_EQ(Json("/api/datasets").size(), 1u);
}

// Observation 4: `method=bad%FFname` broke the leaderboard with 500s; `%00nul` was stored.
TEST_F(ServerTest, Issue27Obs4_RequestTextIsCheckedAtTheDoorAndStoredTextNeverBreaksAPage) {
  const std::string good = testing::RendersFromPhotos(root_, "tiny", 0.0, rng_);
  for (const std::string method : {"bad%FFname", "%00nul", "tab%09", "del%7F", "c1%C2%85",
                                   "overlong%C0%AF", "surrogate%ED%A0%80"}) {
    const auto res = Submit(alice_, good, method);
    ASSERT_TRUE(res);
    EXPECT_EQ(res->status, 400) << method << ": " << res->body;
    EXPECT_NE(res->body.find("not UTF-8 text without control characters"), std::string::npos);
  }
  const auto description =
      client_->Post("/api/datasets/tiny/submissions?method=m&description=a%00b",
                    {{"Authorization", "Bearer " + alice_}}, good, "application/x-tar");
  EXPECT_EQ(description->status, 400);
  EXPECT_EQ(client_->Get("/api/datasets/%FF")->status, 400);
  EXPECT_EQ(client_->Get("/api/datasets/tiny/leaderboard?x=%FF")->status, 400);
  // Clean text of any script is fine and comes back as sent.
  const std::string id = SubmitOk(alice_, good, "Caf%C3%A9%20%E6%B8%B2%E6%9F%93");
  ASSERT_TRUE(server_->submissions().WaitIdle(60));
  EXPECT_EQ(Json("/api/submissions/" + id)["method"], "Caf\xc3\xa9 \xe6\xb8\xb2\xe6\x9f\x93");
  // A row written around the checks (by hand, or by an older server): every response works.
  const SubmissionRecord done = *server_->store().FindSubmission(id);
  SubmissionRecord bad = done;
  bad.id = std::string(31, 'b') + "c";
  bad.method = "bad\xff" + std::string("name\0nul", 8);
  bad.description = "\xfe\xfe";
  ASSERT_TRUE(server_->store().AddSubmission(bad, 1000, 3600));
  server_->store().SetStatus(bad.id, SubmissionStatus::kDone, "\xff", done.summary, done.scores);
  const nlohmann::json board = Json("/api/datasets/tiny/leaderboard");
  ASSERT_EQ(board["entries"].size(), 2u);
  EXPECT_EQ(Json("/api/submissions/" + bad.id)["status"], "done");
  for (const std::string& body : EveryResponse(*client_, {id, bad.id}, alice_)) {
    EXPECT_FALSE(body.empty());
  }
}

// Observation 5: 8 connections sending one byte per second made every other request time out.
// Also 200 idle connections from one more address at the same time.
TEST_F(ServerTest, Issue27Obs5_SlowClientsDoNotStopTheService) {
  StopServer();
  ServerOptions options = DefaultOptions();
  // Two attacking addresses hold 2 x 4 threads; the default 32 leave plenty, 16 enough.
  options.http_threads = 16;
  options.max_connections_per_address = 4;
  options.request_timeout = 3;
  StartServer(options);
  // 8 slow clients from 127.0.0.2, each a request line trickled at one byte per second.
  std::atomic<bool> stop = false;
  std::vector<std::thread> slow;
  std::vector<int> statuses(8, 0);
  std::vector<double> closed_after(8, 0);
  for (int i = 0; i < 8; ++i) {
    slow.emplace_back([&, i] {
      const int fd = Connect(port_, "127.0.0.2");
      if (fd < 0) return;
      const std::string request = "GET /api/datasets HTTP/1.1\r\nHost: x\r\n\r\n";
      const Clock::time_point start = Clock::now();
      std::string response;
      for (size_t k = 0; k < request.size() && !stop; ++k) {
        if (send(fd, &request[k], 1, MSG_NOSIGNAL) != 1) break;
        pollfd readable{fd, POLLIN, 0};
        if (poll(&readable, 1, 1000) > 0) break;  // answered or closed
      }
      char buffer[4096];
      pollfd readable{fd, POLLIN, 0};
      if (poll(&readable, 1, 2000) > 0) {
        const ssize_t n = recv(fd, buffer, sizeof(buffer), 0);
        if (n > 0) response.assign(buffer, static_cast<size_t>(n));
      }
      statuses[i] = StatusOf(response);
      closed_after[i] = SecondsSince(start);
      close(fd);
    });
  }
  // And 200 idle connections at once from 127.0.0.3 (the 4 admitted wait for a request, the
  // other 196 are refused without delaying anyone).
  std::vector<int> idle;
  const Clock::time_point connecting = Clock::now();
  for (int i = 0; i < 200; ++i) {
    const int fd = Connect(port_, "127.0.0.3");
    if (fd >= 0) idle.push_back(fd);
  }
  EXPECT_EQ(idle.size(), 200u);
  // With cpp-httplib's listen backlog of 5 some SYNs were dropped and retried after 1 s each.
  EXPECT_LT(SecondsSince(connecting), 1.0);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  // Probes from 127.0.0.1 while they trickle: each answered within 1 s.
  double slowest = 0;
  for (int probe = 0; probe < 8; ++probe) {
    httplib::Client client("127.0.0.1", port_);
    client.set_connection_timeout(2);
    client.set_read_timeout(2);
    const Clock::time_point start = Clock::now();
    const auto res = client.Get("/api/datasets");
    const double seconds = SecondsSince(start);
    slowest = std::max(slowest, seconds);
    EXPECT_TRUE(res && res->status == 200) << "probe " << probe;
    EXPECT_LT(seconds, 1.0) << "probe " << probe;
    std::this_thread::sleep_for(std::chrono::milliseconds(400));
  }
  stop = true;
  for (std::thread& thread : slow) thread.join();
  for (const int fd : idle) close(fd);
  // 4 admitted and cut at the 3 s deadline (408); 4 refused at once (503).
  std::string all;
  for (int i = 0; i < 8; ++i)
    all += fmt::format("{} after {:.1f} s; ", statuses[i], closed_after[i]);
  EXPECT_EQ(std::count(statuses.begin(), statuses.end(), 408), 4) << all;
  EXPECT_EQ(std::count(statuses.begin(), statuses.end(), 503), 4);
  for (int i = 0; i < 8; ++i) EXPECT_LT(closed_after[i], 5.0) << i;
  RecordProperty("slowest_probe_ms", static_cast<int>(slowest * 1000));
}

// Observation 6: a second server on the same port started and shared the connections.
TEST_F(ServerTest, Issue27Obs6_APortInUseIsAnErrorNamingIt) {
  const fs::path other = base_ / "other-root";
  fs::create_directories(other);
  ServerOptions options = DefaultOptions();
  options.port = port_;
  Server second(other, options);
  const std::string error = rephoto::testing::ErrorOf([&] { second.Bind(); });
  EXPECT_NE(error.find(fmt::format("127.0.0.1:{}", port_)), std::string::npos) << error;
  EXPECT_NE(error.find(fmt::format("port {} is in use", port_)), std::string::npos) << error;
  // Every request still reaches this server.
  for (int i = 0; i < 10; ++i) EXPECT_EQ(Json("/api/datasets")[0]["name"], "tiny");
}

// Observation 7: summary.parameters.photos was the secret folder's absolute path; a failed
// submission's reason began with an absolute path.
TEST_F(ServerTest, Issue27Obs7_NoServerPathInAnyResponse) {
  const std::string good = SubmitOk(alice_, testing::RendersFromPhotos(root_, "tiny", 0.05, rng_));
  const std::string png = ReadFileToString(SecretPhotoFolder(root_, "tiny") / "00.png");
  const std::string failed = SubmitOk(
      alice_, MakeArchive({{"00.png", png.substr(0, png.size() / 2)}}, ArchiveFormat::kTar));
  ASSERT_TRUE(server_->submissions().WaitIdle(60));
  EXPECT_EQ(Json("/api/submissions/" + failed)["status"], "failed");
  const std::string absolute_root = fs::absolute(root_).string();
  for (const std::string& body : EveryResponse(*client_, {good, failed}, alice_)) {
    EXPECT_EQ(body.find(absolute_root), std::string::npos);
    EXPECT_EQ(body.find("/tmp/"), std::string::npos);
    EXPECT_EQ(body.find("secret/"), std::string::npos);
  }
}

// Observation 8: bombs and refused archives did not count towards the rate limit.
TEST_F(ServerTest, Issue27Obs8_RefusedUploadsCountTowardsTheRateLimitAndLeaveNothing) {
  StopServer();
  ServerOptions options = DefaultOptions();
  options.limits.max_per_window = 3;
  StartServer(options);
  const std::string png = ReadFileToString(SecretPhotoFolder(root_, "tiny") / "00.png");
  EXPECT_EQ(
      Submit(bob_, MakeArchive({{"00.png", std::string(50 << 20, '\0')}}, ArchiveFormat::kZip))
          ->status,
      413);
  EXPECT_EQ(Submit(bob_, std::string(5000, 'x'))->status, 400);
  EXPECT_EQ(Submit(bob_, MakeArchive({{"../00.png", png}}, ArchiveFormat::kTar))->status, 400);
  const auto refused = Submit(bob_, testing::RendersFromPhotos(root_, "tiny", 0.0, rng_));
  EXPECT_EQ(refused->status, 429) << refused->body;
  const nlohmann::json history = Json("/api/participants/me/submissions", bob_);
  EXPECT_EQ(history["quota"]["used"], 3);
  EXPECT_EQ(history["quota"]["remaining"], 0);
  EXPECT_TRUE(history["submissions"].empty());
  EXPECT_TRUE(!fs::exists(root_ / "submissions") || fs::is_empty(root_ / "submissions"));
  EXPECT_EQ(Submit(alice_, testing::RendersFromPhotos(root_, "tiny", 0.0, rng_))->status, 202);
  ASSERT_TRUE(server_->submissions().WaitIdle(60));
}

// Observation 9: a submission rendering only the object ranked above complete ones.
TEST_F(ServerTest, Issue27Obs9_RenderingLessNeverRanksHigher) {
  { AddTinyDatasetTo("tiny_min", "min-completeness:0.5"); }
  // The cheat: the top-left 5 % of each photo, perfectly; nothing else. The honest one: every
  // pixel, with noise.
  const std::string cheat = testing::RendersFromPhotos(root_, "tiny", 0.0, rng_, 0.05);
  const std::string honest = testing::RendersFromPhotos(root_, "tiny", 0.08, rng_);
  std::map<std::string, std::string> ids;
  for (const std::string dataset : {"tiny", "tiny_min"}) {
    dataset_ = dataset;
    ids[dataset + "/cheat"] = SubmitOk(alice_, cheat, "cheat");
    ids[dataset + "/honest"] = SubmitOk(bob_, honest, "honest");
  }
  ASSERT_TRUE(server_->submissions().WaitIdle(120));
  // By the mean over covered pixels alone, the cheat would win (what the old server ranked by).
  const nlohmann::json cheat_scores = Json("/api/submissions/" + ids["tiny/cheat"], alice_);
  const nlohmann::json honest_scores = Json("/api/submissions/" + ids["tiny/honest"]);
  const double cheat_mean = JsonNumber(cheat_scores["scores"]["all"]["means"]["1-ncc"]);
  const double honest_mean = JsonNumber(honest_scores["scores"]["all"]["means"]["1-ncc"]);
  EXPECT_LT(cheat_mean, 0.01);
  EXPECT_GT(honest_mean, 0.05);
  EXPECT_LT(JsonNumber(cheat_scores["scores"]["all"]["completeness"]), 0.1);
  EXPECT_GT(JsonNumber(honest_scores["scores"]["all"]["completeness"]), 0.99);
  // "filled": each photo's uncovered part counts at 1-ncc's worst, 2.
  double expected = 0;
  for (const auto& row : cheat_scores["images"]) {
    const double c = JsonNumber(row["completeness"]);
    expected += (c * JsonNumber(row["1-ncc"]) + (1 - c) * 2.0) / 2;
  }
  EXPECT_NEAR(JsonNumber(cheat_scores["scores"]["all"]["filled"]["1-ncc"]), expected, 1e-12);
  EXPECT_GT(expected, 1.8);
  const double honest_filled = JsonNumber(honest_scores["scores"]["all"]["filled"]["1-ncc"]);
  EXPECT_LT(honest_filled, expected);
  std::fprintf(stderr,
               "1-ncc: cheat mean %.4f filled %.4f completeness %.4f; honest mean %.4f filled %.4f "
               "completeness %.4f\n",
               cheat_mean, expected, JsonNumber(cheat_scores["scores"]["all"]["completeness"]),
               honest_mean, honest_filled,
               JsonNumber(honest_scores["scores"]["all"]["completeness"]));
  const nlohmann::json board = Json("/api/datasets/tiny/leaderboard");
  EXPECT_EQ(board["ranking"]["rule"], "filled");
  ASSERT_EQ(board["entries"].size(), 2u);
  EXPECT_EQ(board["entries"][0]["method"], "honest");
  EXPECT_EQ(board["entries"][1]["method"], "cheat");
  // min-completeness:0.5: the cheat is not ranked at all, listed apart.
  const nlohmann::json min_board = Json("/api/datasets/tiny_min/leaderboard");
  EXPECT_EQ(min_board["ranking"]["rule"], "min-completeness:0.5");
  ASSERT_EQ(min_board["entries"].size(), 1u);
  EXPECT_EQ(min_board["entries"][0]["method"], "honest");
  ASSERT_EQ(min_board["unranked"].size(), 1u);
  EXPECT_EQ(min_board["unranked"][0]["method"], "cheat");
  // Every leaderboard states its rule, in the API and on the page.
  for (const std::string dataset : {"tiny", "tiny_min"}) {
    const std::string page = client_->Get(("/datasets/" + dataset + "/leaderboard").c_str())->body;
    EXPECT_NE(page.find(Json("/api/datasets/" + dataset + "/leaderboard")["ranking"]["rule"]
                            .get<std::string>()),
              std::string::npos);
    EXPECT_NE(page.find("id=\"ranking\""), std::string::npos);
  }
}

// Point 9 of the brief: the public/private split, best per method, history and quota.
TEST_F(ServerTest, APublicPrivateSplitHidesThePrivatePhotosUntilTheReveal) {
  AddTinyDatasetTo("tiny_split", "filled", 0.5);
  dataset_ = "tiny_split";
  const std::string first = SubmitOk(alice_, testing::RendersFromPhotos(root_, "tiny", 0.1, rng_));
  const std::string second =
      SubmitOk(alice_, testing::RendersFromPhotos(root_, "tiny", 0.02, rng_));
  ASSERT_TRUE(server_->submissions().WaitIdle(60));
  const DatasetRecord dataset = *server_->store().FindDataset("tiny_split");
  const auto public_stems = dataset.info["settings"]["public_stems"];
  ASSERT_EQ(public_stems.size(), 1u);
  // Which photo is public is not published.
  EXPECT_FALSE(Json("/api/datasets/tiny_split")["settings"].contains("public_stems"));
  EXPECT_EQ(Json("/api/datasets/tiny_split")["split"]["private"], 1);
  // Before the reveal: the public photo ranks; nothing of the private one is shown.
  nlohmann::json board = Json("/api/datasets/tiny_split/leaderboard");
  EXPECT_EQ(board["photos"]["subset"], "public");
  EXPECT_EQ(board["photos"]["count"], 1);
  ASSERT_EQ(board["entries"].size(), 1u);  // alice's best "m" only
  EXPECT_EQ(board["entries"][0]["id"], second);
  EXPECT_EQ(Json("/api/datasets/tiny_split/leaderboard?all=1")["entries"].size(), 2u);
  nlohmann::json own = Json("/api/submissions/" + second, alice_);
  EXPECT_FALSE(own.contains("summary"));
  EXPECT_FALSE(own["scores"].contains("private"));
  EXPECT_FALSE(own["scores"].contains("all"));
  ASSERT_EQ(own["images"].size(), 1u);
  EXPECT_EQ(own["images"][0]["name"], public_stems[0]);
  // History and quota.
  const nlohmann::json history = Json("/api/participants/me/submissions", alice_);
  ASSERT_EQ(history["submissions"].size(), 2u);
  EXPECT_EQ(history["submissions"][0]["id"], second);
  EXPECT_EQ(history["quota"]["used"], 2);
  EXPECT_EQ(history["quota"]["remaining"], 28);
  // After the reveal: the private photo ranks, every score is shown.
  RevealDataset(server_->store(), "tiny_split");
  board = Json("/api/datasets/tiny_split/leaderboard");
  EXPECT_EQ(board["photos"]["subset"], "private");
  EXPECT_TRUE(board["revealed"]);
  ASSERT_EQ(board["entries"].size(), 1u);
  EXPECT_TRUE(board["entries"][0].contains("public"));
  own = Json("/api/submissions/" + second, alice_);
  EXPECT_TRUE(own["scores"].contains("private"));
  EXPECT_TRUE(own.contains("summary"));
  EXPECT_EQ(own["images"].size(), 2u);
  (void)first;
}

// Point 8 of the brief: one access-log line per request, in the common log format, no token.
TEST_F(ServerTest, TheAccessLogHasOneLinePerRequestAndNoToken) {
  StopServer();
  ServerOptions options = DefaultOptions();
  options.access_log = (base_ / "access.log").string();
  StartServer(options);
  EXPECT_EQ(Submit(alice_, "not an archive")->status, 400);
  Json("/api/datasets");
  EXPECT_EQ(client_->Get("/nothing")->status, 404);
  StopServer();
  const std::string log = ReadFileToString(base_ / "access.log");
  const std::regex line(
      R"(127\.0\.0\.1 - - \[\d\d/[A-Z][a-z]{2}/\d{4}:\d\d:\d\d:\d\d \+0000\] "(GET|POST) /\S* HTTP/1\.1" \d{3} \d+)");
  std::istringstream lines(log);
  std::vector<std::string> all;
  for (std::string text; std::getline(lines, text);) {
    EXPECT_TRUE(std::regex_match(text, line)) << text;
    all.push_back(text);
  }
  ASSERT_EQ(all.size(), 3u) << log;
  // One line per request; not necessarily in request order: each request may come on its own
  // connection, and the server thread that answered it writes its line after the response.
  const auto count = [&](const std::string& needle) {
    return std::count_if(all.begin(), all.end(), [&](const std::string& text) {
      return text.find(needle) != std::string::npos;
    });
  };
  EXPECT_EQ(count("\"POST /api/datasets/tiny/submissions HTTP/1.1\" 400 "), 1) << log;
  EXPECT_EQ(count("\"GET /api/datasets HTTP/1.1\" 200 "), 1) << log;
  EXPECT_EQ(count("\"GET /nothing HTTP/1.1\" 404 "), 1) << log;
  EXPECT_EQ(log.find(alice_), std::string::npos);
  EXPECT_EQ(log.find(alice_.substr(4, 16)), std::string::npos);
}

// Peak RSS of a `rephoto serve` process (VmHWM, kB).
long PeakRssKb(pid_t pid) {
  std::ifstream status(fmt::format("/proc/{}/status", pid));
  for (std::string line; std::getline(status, line);) {
    if (line.rfind("VmHWM:", 0) == 0) return std::stol(line.substr(6));
  }
  return -1;
}

// Observation 2 on a server process: 300 MiB chunked, 300 MiB without a length and a gzip body
// that inflates to 200 MiB; peak RSS stays under 2 x max_body + 200 MB.
TEST_F(ServerTest, Issue27Obs2_OversizedBodiesKeepAServerProcessSmall) {
  StopServer();
  const size_t max_body = 10000000;
  const fs::path log = base_ / "serve.log";
  std::vector<std::string> args = {REPHOTO_CLI,    "serve",
                                   "--root",       root_.string(),
                                   "--listen",     "127.0.0.1:0",
                                   "--max-body",   std::to_string(max_body),
                                   "--access-log", ""};
  std::vector<char*> argv;
  for (std::string& arg : args) argv.push_back(arg.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 2, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  pid_t pid = 0;
  ASSERT_EQ(posix_spawn(&pid, REPHOTO_CLI, &actions, nullptr, argv.data(), environ), 0);
  posix_spawn_file_actions_destroy(&actions);
  int port = 0;
  const std::regex serving(R"(on http://127\.0\.0\.1:(\d+)/)");
  for (int i = 0; i < 300 && port == 0; ++i) {
    std::smatch match;
    const std::string text = fs::exists(log) ? ReadFileToString(log) : "";
    if (std::regex_search(text, match, serving)) port = std::stoi(match[1]);
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_GT(port, 0);
  const long before = PeakRssKb(pid);
  const std::string piece(1 << 20, 'x');
  const size_t total = size_t{300} << 20;
  const std::string target = "POST /api/datasets/tiny/submissions?method=m HTTP/1.1\r\n";
  const std::string auth = "Authorization: Bearer " + alice_ + "\r\n";
  const std::string type = "Content-Type: application/x-tar\r\n";
  Streamed r = SendStreaming(port, target + auth + type + "Transfer-Encoding: chunked\r\n\r\n",
                             [&](size_t sent) { return sent < total ? Chunk(piece) : ""; });
  EXPECT_EQ(StatusOf(r.response), 413);
  r = SendStreaming(port, target + type + "Transfer-Encoding: chunked\r\n\r\n",
                    [&](size_t sent) { return sent < total ? Chunk(piece) : ""; });
  EXPECT_EQ(StatusOf(r.response), 401);
  r = SendStreaming(port, target + auth + type + "Connection: close\r\n\r\n",
                    [&](size_t sent) { return sent < total ? piece : ""; });
  EXPECT_EQ(StatusOf(r.response), 413);
  const fs::path gz = base_ / "bomb.gz";
  ASSERT_EQ(std::system(("head -c 200M /dev/zero | gzip -1 > '" + gz.string() + "'").c_str()), 0);
  const std::string bomb = ReadFileToString(gz);
  r = SendStreaming(port,
                    target + auth + type + "Content-Encoding: gzip\r\n" +
                        fmt::format("Content-Length: {}\r\n\r\n", bomb.size()),
                    [&](size_t sent) { return sent < bomb.size() ? bomb.substr(sent) : ""; });
  EXPECT_EQ(StatusOf(r.response), 415);
  const long peak = PeakRssKb(pid);
  EXPECT_LT(peak * 1024, static_cast<long>(2 * max_body + 200'000'000))
      << "peak RSS " << peak << " kB (" << before << " kB before)";
  RecordProperty("peak_rss_kb", static_cast<int>(peak));
  kill(pid, SIGTERM);
  int status = 0;
  waitpid(pid, &status, 0);
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << ReadFileToString(log);
  std::fprintf(stderr, "peak RSS of the server: %ld kB before the attacks, %ld kB after\n", before,
               peak);
}

}  // namespace
}  // namespace rephoto::service
