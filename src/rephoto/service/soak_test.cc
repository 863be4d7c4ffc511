// Soak (issue 27 acceptance): 10,000 mixed hostile requests from 3 client threads, interleaved
// with 20 honest submissions, against one in-process server on 127.0.0.1. Afterwards every
// honest submission is scored with exactly `rephoto compare`'s numbers on its renders, the
// server answers, nothing of a refused upload is left on disk and SQLite's integrity check is
// ok. Each hostile request must get its documented status (a 503 from the per-address bound is
// allowed for any; no other 5xx ever).
#include <sqlite3.h>

#include <atomic>
#include <map>
#include <mutex>
#include <set>

#include "rephoto/compare/compare.h"
// Last: it includes httplib (see there).
#include "rephoto/service/server_fixture.h"

namespace rephoto::service {
namespace {
namespace fs = std::filesystem;
using testing::ArchiveFormat;
using testing::Chunk;
using testing::MakeArchive;
using testing::SendStreaming;
using testing::ServerTest;
using testing::StatusOf;

constexpr int kHostileRequests = 10000;
constexpr int kHonestSubmissions = 20;

// One kind of hostile request: what to send, and the statuses it may get.
struct Attack {
  std::string name;
  std::function<std::string(int port)> send;  // the response
  std::set<int> statuses;
};

TEST_F(ServerTest, SoakOf10000HostileRequestsAnd20HonestSubmissions) {
  StopServer();
  ServerOptions options = DefaultOptions();
  options.http_threads = 16;
  // 3 clients that close and reconnect at once: the server may not have seen the close yet.
  options.max_connections_per_address = 12;
  options.limits.max_per_window = 1000000;
  options.header_timeout = 2;
  StartServer(options);

  const std::string png = ReadFileToString(SecretPhotoFolder(root_, "tiny") / "00.png");
  const std::string bomb =
      MakeArchive({{"00.png", std::string(8 << 20, '\0')}}, ArchiveFormat::kZip);
  const std::string bad_name = MakeArchive({{"\xff\xfe.png", png}}, ArchiveFormat::kTar);
  const std::string traversal = MakeArchive({{"../../00.png", png}}, ArchiveFormat::kTar);
  const std::string post = "POST /api/datasets/tiny/submissions?method=m HTTP/1.1\r\nHost: x\r\n";
  const std::string auth = "Authorization: Bearer " + alice_ + "\r\n";
  const std::string tar = "Content-Type: application/x-tar\r\n";
  const auto with_body = [](const std::string& head, const std::string& body) {
    return [head, body](int port) {
      return SendStreaming(port, head + fmt::format("Content-Length: {}\r\n\r\n", body.size()),
                           [&](size_t sent) { return sent < body.size() ? body.substr(sent) : ""; })
          .response;
    };
  };
  const auto raw = [](const std::string& request) {
    return [request](int port) {
      return SendStreaming(port, request, [](size_t) { return std::string(); }).response;
    };
  };
  const std::string piece(32 << 10, 'x');
  const std::vector<Attack> attacks = {
      {"traversal path",
       raw("GET /api/datasets/tiny/..%2f..%2fsecret%2ftiny HTTP/1.1\r\n\r\n"),
       {404}},
      {"secret path", raw("GET /secret/tiny/photos/00.png HTTP/1.1\r\n\r\n"), {404}},
      {"invalid utf-8 path", raw("GET /api/datasets/%FF%FE HTTP/1.1\r\n\r\n"), {400}},
      {"nul in query", raw("GET /api/datasets/tiny/leaderboard?all=%00 HTTP/1.1\r\n\r\n"), {400}},
      {"leaderboard",
       raw("GET /api/datasets/tiny/leaderboard HTTP/1.1\r\nConnection: close\r\n\r\n"),
       {200}},
      {"page", raw("GET /datasets/tiny/leaderboard HTTP/1.1\r\nConnection: close\r\n\r\n"), {200}},
      {"no token", with_body(post + tar, bomb), {401}},
      {"wrong token", with_body(post + tar + "Authorization: Bearer rp1_x\r\n", bomb), {401}},
      {"method %FF",
       with_body("POST /api/datasets/tiny/submissions?method=bad%FFname HTTP/1.1\r\n" + auth + tar,
                 traversal),
       {400}},
      {"method %00",
       with_body("POST /api/datasets/tiny/submissions?method=%00nul HTTP/1.1\r\n" + auth + tar,
                 traversal),
       {400}},
      {"member \\xff\\xfe.png", with_body(post + auth + tar, bad_name), {400}},
      {"member ../../00.png", with_body(post + auth + tar, traversal), {400}},
      {"not an archive", with_body(post + auth + tar, std::string(3000, 'x')), {400}},
      {"zip bomb", with_body(post + auth + tar, bomb), {413}},
      {"declared too large",
       raw(post + auth + tar + "Content-Length: 999999999999\r\n\r\n"),
       {413}},
      {"chunked too large",
       [&](int port) {
         return SendStreaming(port, post + auth + tar + "Transfer-Encoding: chunked\r\n\r\n",
                              [&](size_t sent) {
                                return sent < (size_t{2} << 20) ? Chunk(piece) : "0\r\n\r\n";
                              })
             .response;
       },
       {413}},
      {"gzip encoding", with_body(post + auth + tar + "Content-Encoding: gzip\r\n", bomb), {415}},
      {"form encoded",
       with_body(post + auth + "Content-Type: application/x-www-form-urlencoded\r\n", "a=b"),
       {415}},
      {"multipart without length",
       raw(post + auth +
           "Content-Type: multipart/form-data; boundary=x\r\n"
           "Transfer-Encoding: chunked\r\n\r\n0\r\n\r\n"),
       {411}},
      {"put", with_body("PUT /api/datasets HTTP/1.1\r\n", "x"), {405}},
      {"get with body", with_body("GET /api/datasets HTTP/1.1\r\n", "xyz"), {400}},
      {"no such dataset",
       with_body("POST /api/datasets/nope/submissions?method=m HTTP/1.1\r\n" + auth + tar, "x"),
       {404}},
      {"tls hello",
       raw(std::string("\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03", 11) + "\r\n\r\n"),
       {0, 400}},
      {"header flood",
       raw("GET / HTTP/1.1\r\nX: " + std::string(20000, 'a') + "\r\n\r\n"),
       {0, 400, 431}},
      {"garbage line", raw("\x01\x02\x03 / HTTP/1.1\r\n\r\n"), {0, 400}},
  };

  // The honest submissions: RendersFromPhotos with noise 0.01 .. 0.2, submitted by bob.
  std::vector<std::string> honest_archives;
  for (int i = 0; i < kHonestSubmissions; ++i) {
    honest_archives.push_back(testing::RendersFromPhotos(root_, "tiny", 0.01 * (i + 1), rng_));
  }
  std::mutex mutex;
  std::map<std::string, int> unexpected;  // "<attack>: <status>" -> count
  std::vector<std::string> honest_ids(kHonestSubmissions);
  std::atomic<int> next = 0;
  std::atomic<int> answered = 0, refused_connections = 0;
  const auto client = [&] {
    httplib::Client honest_client("127.0.0.1", port_);
    honest_client.set_read_timeout(60);
    for (int i; (i = next++) < kHostileRequests;) {
      if (i % (kHostileRequests / kHonestSubmissions) == 0) {
        const int k = i / (kHostileRequests / kHonestSubmissions);
        for (int attempt = 0; attempt < 20; ++attempt) {
          const auto res = honest_client.Post(
              fmt::format("/api/datasets/tiny/submissions?method=honest{}", k).c_str(),
              {{"Authorization", "Bearer " + bob_}}, honest_archives[k], "application/x-tar");
          if (res && res->status == 202) {
            honest_ids[k] = nlohmann::json::parse(res->body)["id"];
            break;
          }
          std::this_thread::sleep_for(std::chrono::milliseconds(50));  // 503: retry
        }
      }
      const Attack& attack = attacks[i % attacks.size()];
      const int status = StatusOf(attack.send(port_));
      ++answered;
      if (status == 503) {
        ++refused_connections;
      } else if (!attack.statuses.count(status)) {
        std::lock_guard lock(mutex);
        ++unexpected[fmt::format("{}: {}", attack.name, status)];
      }
    }
  };
  std::vector<std::thread> clients;
  for (int t = 0; t < 3; ++t) clients.emplace_back(client);
  for (std::thread& thread : clients) thread.join();
  EXPECT_EQ(answered, kHostileRequests);
  for (const auto& [what, count] : unexpected) ADD_FAILURE() << what << " (" << count << "x)";
  EXPECT_LT(refused_connections, kHostileRequests / 100);
  std::fprintf(stderr, "%d hostile requests, %d refused by the per-address bound\n",
               answered.load(), refused_connections.load());

  // Every honest submission scored as `rephoto compare` scores its renders.
  ASSERT_TRUE(server_->submissions().WaitIdle(600));
  for (int k = 0; k < kHonestSubmissions; ++k) {
    const std::string& id = honest_ids[k];
    ASSERT_FALSE(id.empty()) << "honest submission " << k << " was not accepted";
    const nlohmann::json submission = Json("/api/submissions/" + id);
    ASSERT_EQ(submission["status"], "done") << k;
    compare::CompareOptions compare_options;
    compare_options.photos = SecretPhotoFolder(root_, "tiny");
    compare_options.renders = SubmissionFolder(root_, id) / "renders";
    compare_options.out = rephoto::testing::MakeTempDir() / "compare";
    compare_options.metrics = metrics::ParseMetricList("1-ncc,cb+cr,psnr");
    compare_options.metric_options.window = 5;
    compare_options.write_error_images = false;
    compare::RunCompare(compare_options);
    EXPECT_EQ(submission["summary"], PublicSummary(nlohmann::json::parse(
                                         ReadFileToString(compare_options.out / "summary.json"))))
        << k;
  }
  EXPECT_EQ(Json("/api/datasets/tiny/leaderboard?all=1")["entries"].size(),
            static_cast<size_t>(kHonestSubmissions));
  // Nothing but the honest submissions' folders.
  size_t folders = 0;
  for (const auto& entry : fs::directory_iterator(root_ / "submissions")) {
    EXPECT_EQ(entry.path().filename().string().rfind(".incoming-", 0), std::string::npos);
    ++folders;
  }
  EXPECT_EQ(folders, static_cast<size_t>(kHonestSubmissions));
  StopServer();
  sqlite3* db = nullptr;
  ASSERT_EQ(sqlite3_open((root_ / "benchmark.sqlite").c_str(), &db), SQLITE_OK);
  sqlite3_stmt* check = nullptr;
  ASSERT_EQ(sqlite3_prepare_v2(db, "PRAGMA integrity_check", -1, &check, nullptr), SQLITE_OK);
  ASSERT_EQ(sqlite3_step(check), SQLITE_ROW);
  EXPECT_STREQ(reinterpret_cast<const char*>(sqlite3_column_text(check, 0)), "ok");
  sqlite3_finalize(check);
  sqlite3_close(db);
}

}  // namespace
}  // namespace rephoto::service
