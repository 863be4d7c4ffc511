// The HTTP service end to end on 127.0.0.1 (an in-process Server on a free port): the API, the
// limits and refusals with their status codes, that no URL spelling returns a byte of a secret
// photo, and that a submission's scores are exactly `rephoto compare`'s on the same files.
#include "rephoto/benchmark/server.h"

#include "rephoto/compare/compare.h"
#include "rephoto/io/image_io.h"
// Last: it includes httplib (see there).
#include "rephoto/benchmark/server_fixture.h"

namespace rephoto::benchmark {
namespace {
namespace fs = std::filesystem;
using testing::ArchiveFormat;
using testing::MakeArchive;
using testing::RawHttp;
using testing::ServerTest;
using Type = testing::TestEntry::Type;

TEST_F(ServerTest, ListsDatasetsAndPublishesTrainingAndTestCameras) {
  const nlohmann::json list = Json("/api/datasets");
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0]["name"], "tiny");
  EXPECT_EQ(list[0]["training_images"], 4);  // every:3 of 6: 00 and 03 are test images
  EXPECT_EQ(list[0]["test_images"], 2);
  const nlohmann::json dataset = Json("/api/datasets/tiny");
  EXPECT_EQ(dataset["test_images"][0]["stem"], "00");
  EXPECT_EQ(dataset["test_images"][1]["stem"], "03");
  EXPECT_EQ(dataset["test_images"][0]["width"], 64);
  EXPECT_EQ(dataset["settings"]["metrics"], nlohmann::json({"1-ncc", "cb+cr", "psnr"}));
  // The downloads, read back by the system's tar: what they hold, and no test photo.
  const fs::path work = rephoto::testing::MakeTempDir();
  for (const std::string name : {"training.tar", "test-cameras.tar"}) {
    const auto res = client_->Get(("/api/datasets/tiny/" + name).c_str());
    ASSERT_TRUE(res && res->status == 200) << name;
    WriteTextFileAtomically(work / name, res->body);
    fs::create_directories(work / (name + ".d"));
    ASSERT_EQ(std::system(("tar xf '" + (work / name).string() + "' -C '" +
                           (work / (name + ".d")).string() + "'")
                              .c_str()),
              0);
    for (const std::string& photo : SecretPhotos()) {
      EXPECT_EQ(res->body.find(photo), std::string::npos) << name;
    }
  }
  const fs::path training = work / "training.tar.d";
  for (const char* file : {"01.png", "02.png", "04.png", "05.png"}) {
    EXPECT_TRUE(fs::exists(training / "images" / file)) << file;
  }
  EXPECT_FALSE(fs::exists(training / "images" / "00.png"));
  EXPECT_FALSE(fs::exists(training / "images" / "03.png"));
  EXPECT_TRUE(fs::exists(training / "sparse" / "images.txt"));
  EXPECT_TRUE(fs::exists(training / "transforms.json"));
  const fs::path test = work / "test-cameras.tar.d";
  EXPECT_EQ(ReadFileToString(test / "test_images.txt"), "00\n03\n");
  EXPECT_TRUE(fs::exists(test / "sparse" / "cameras.txt"));
  EXPECT_FALSE(fs::exists(test / "images"));
}

TEST_F(ServerTest, NoUrlSpellingReturnsAByteOfASecretPhoto) {
  const std::string absolute = fs::absolute(SecretPhotoFolder(root_, "tiny") / "00.png").string();
  const std::vector<std::string> paths = {
      "/secret/tiny/photos/00.png",
      "/root/secret/tiny/photos/00.png",
      "/../secret/tiny/photos/00.png",
      "/api/datasets/tiny/../../../secret/tiny/photos/00.png",
      "/api/datasets/tiny/%2e%2e/%2e%2e/secret/tiny/photos/00.png",
      "/api/datasets/tiny/%2E%2E%2F%2E%2E%2Fsecret%2Ftiny%2Fphotos%2F00.png",
      "/api/datasets/tiny/..%2f..%2fsecret%2ftiny%2fphotos%2f00.png",
      "/api/datasets/%2e%2e/secret",
      "/api/datasets/tiny//secret/tiny/photos/00.png",
      "//secret/tiny/photos/00.png",
      "/api/datasets/tiny/" + absolute,
      "/api/datasets/tiny/" + absolute.substr(1),
      "/api/datasets/tiny/%2F" + absolute.substr(1),
      "/api/datasets/tiny/00.png",
      "/api/datasets/tiny/photos",
      "/api/datasets/tiny/secret",
      "/api/datasets/tiny/test-cameras.tar/../../../secret/tiny/photos/00.png",
      "/api/datasets/tiny/training.tar%00../../secret/tiny/photos/00.png",
      "/api/submissions/../secret/tiny/photos/00.png",
      "/api/submissions/00000000000000000000000000000000/errors/00.1-ncc.png",
      "/datasets/tiny/../../secret/tiny/photos/00.png",
      "/public/tiny/training.tar",
      "/benchmark.sqlite",
      "/api/datasets/tiny/benchmark.sqlite",
      absolute,
      "http://127.0.0.1/" + absolute,
  };
  const std::vector<std::string> photos = SecretPhotos();
  ASSERT_EQ(photos.size(), 2u);
  for (const std::string& path : paths) {
    const std::string response =
        RawHttp(port_, "GET " + path + " HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n");
    EXPECT_TRUE(response.rfind("HTTP/1.1 404", 0) == 0 || response.rfind("HTTP/1.1 400", 0) == 0)
        << path << ": " << response.substr(0, 40);
    for (const std::string& photo : photos) {
      // Not the file, nor any 64-byte piece of it (its PNG header and first bytes aside).
      for (size_t offset = 64; offset + 64 <= photo.size(); offset += 64) {
        ASSERT_EQ(response.find(photo.substr(offset, 64)), std::string::npos) << path;
      }
    }
  }
  // The server still serves.
  EXPECT_EQ(Json("/api/datasets").size(), 1u);
}

TEST_F(ServerTest, ScoresExactlyAsRephotoCompareAndRanksTheLeaderboard) {
  const auto perfect =
      Submit(alice_, testing::RendersFromPhotos(root_, "tiny", 0.0, rng_), "exact");
  ASSERT_TRUE(perfect);
  ASSERT_EQ(perfect->status, 202) << perfect->body;
  const auto noisy = Submit(bob_, testing::RendersFromPhotos(root_, "tiny", 0.1, rng_), "noisy");
  ASSERT_EQ(noisy->status, 202) << noisy->body;
  const std::string perfect_id = nlohmann::json::parse(perfect->body)["id"];
  const std::string noisy_id = nlohmann::json::parse(noisy->body)["id"];
  ASSERT_TRUE(server_->submissions().WaitIdle(120));

  for (const auto& [id, token] : {std::pair{perfect_id, alice_}, std::pair{noisy_id, bob_}}) {
    // Per-photo numbers go to the submission's own participant only.
    EXPECT_FALSE(Json("/api/submissions/" + id).contains("images"));
    const nlohmann::json submission = Json("/api/submissions/" + id, token);
    ASSERT_EQ(submission["status"], "done") << submission.dump();
    // `rephoto compare` on the same photos and renders, with the dataset's settings.
    compare::CompareOptions options;
    options.photos = SecretPhotoFolder(root_, "tiny");
    options.renders = SubmissionFolder(root_, id) / "renders";
    options.out = rephoto::testing::MakeTempDir() / "compare";
    options.metrics = metrics::ParseMetricList("1-ncc,cb+cr,psnr");
    options.metric_options.window = 5;
    options.write_error_images = false;
    compare::RunCompare(options);
    EXPECT_EQ(submission["summary"],
              PublicSummary(nlohmann::json::parse(ReadFileToString(options.out / "summary.json"))));
    EXPECT_FALSE(submission["summary"]["parameters"].contains("photos"));  // no server paths
    ASSERT_EQ(submission["images"].size(), 2u);
    EXPECT_FALSE(submission["images"][0].contains("photo"));  // no server paths
  }
  // Renders equal to the photos: zero error, full coverage (by definition of the metrics).
  const nlohmann::json exact = Json("/api/submissions/" + perfect_id)["summary"];
  EXPECT_EQ(exact["metrics"]["1-ncc"]["mean"], 0.0);
  EXPECT_EQ(exact["metrics"]["psnr"]["mean"], "inf");
  EXPECT_EQ(exact["completeness"]["mean"], 1.0);

  const nlohmann::json board = Json("/api/datasets/tiny/leaderboard");
  EXPECT_EQ(board["headline"], "1-ncc");
  EXPECT_EQ(board["ranking"]["rule"], "filled");
  ASSERT_EQ(board["entries"].size(), 2u);
  EXPECT_EQ(board["entries"][0]["id"], perfect_id);
  EXPECT_EQ(board["entries"][0]["rank"], 1);
  EXPECT_EQ(board["entries"][0]["completeness"], 1.0);
  EXPECT_EQ(board["entries"][1]["id"], noisy_id);
  EXPECT_GT(JsonNumber(board["entries"][1]["headline"]["mean"]), 0.01);
  EXPECT_EQ(board["entries"][1]["metrics"]["cb+cr"],
            Json("/api/submissions/" + noisy_id)["summary"]["metrics"]["cb+cr"]["mean"]);

  // Pages: 200 and the method names.
  for (const std::string& path : std::vector<std::string>{
           "/", "/datasets/tiny", "/datasets/tiny/leaderboard", "/submissions/" + noisy_id}) {
    const auto res = client_->Get(path.c_str());
    ASSERT_TRUE(res && res->status == 200) << path;
    EXPECT_NE(res->body.find("<!DOCTYPE html>"), std::string::npos);
  }
  EXPECT_NE(client_->Get("/datasets/tiny/leaderboard")->body.find("noisy"), std::string::npos);
  EXPECT_EQ(client_->Get("/submissions/nonexistent")->status, 404);
}

TEST_F(ServerTest, RefusesBadTokensWith401) {
  const std::string archive = testing::RendersFromPhotos(root_, "tiny", 0.0, rng_);
  EXPECT_EQ(Submit("", archive)->status, 401);
  EXPECT_EQ(Submit("rp1_" + std::string(64, '0'), archive)->status, 401);
  EXPECT_EQ(Submit(revoked_, archive)->status, 401);
  EXPECT_EQ(Submit(alice_ + "x", archive)->status, 401);
  EXPECT_FALSE(fs::exists(root_ / "submissions") && !fs::is_empty(root_ / "submissions"));
}

TEST_F(ServerTest, RefusesBadArchivesWithTheDocumentedStatusAndKeepsServing) {
  const std::string good = testing::RendersFromPhotos(root_, "tiny", 0.0, rng_);
  ASSERT_EQ(Submit(alice_, good, "first")->status, 202);
  const std::string png = ReadFileToString(SecretPhotoFolder(root_, "tiny") / "00.png");
  // A render of the wrong size.
  Image small(32, 24, 4, 0.5f);
  const fs::path work = rephoto::testing::MakeTempDir();
  io::WritePng(work / "03.png", small);
  struct Case {
    std::string what;
    std::string archive;
    int status;
    std::string reason;
  };
  const std::vector<Case> cases = {
      {"traversal", MakeArchive({{"../../00.png", png}}, ArchiveFormat::kTar), 400, "'..'"},
      {"absolute", MakeArchive({{"/tmp/00.png", png}}, ArchiveFormat::kZip), 400, "absolute"},
      {"symlink", MakeArchive({{"00.png", "", Type::kSymlink, "/etc/passwd"}}, ArchiveFormat::kTar),
       400, "not a regular file"},
      {"device", MakeArchive({{"00.png", "", Type::kCharDevice}}, ArchiveFormat::kTar), 400,
       "not a regular file"},
      {"bomb", MakeArchive({{"00.png", std::string(50 << 20, '\0')}}, ArchiveFormat::kZip), 413,
       "exceed 200000 bytes"},
      {"too many files",
       MakeArchive({{"a", "", Type::kDirectory},
                    {"b", "", Type::kDirectory},
                    {"c", "", Type::kDirectory},
                    {"d", "", Type::kDirectory},
                    {"e/00.png", png}},
                   ArchiveFormat::kTar),
       413, "more than 4 entries"},
      {"body too large", std::string(400000, 'x'), 413, "exceeds the server's limit"},
      {"malformed", std::string(5000, 'x'), 400, "not a tar or zip archive"},
      {"empty", "", 400, "not a tar or zip archive"},
      {"wrong size",
       MakeArchive({{"03.png", ReadFileToString(work / "03.png")}}, ArchiveFormat::kTar), 400,
       "render '03.png' is 32x24, test camera '03' is 64x48"},
      {"not an image", MakeArchive({{"03.png", "hello"}}, ArchiveFormat::kTar), 400,
       "not a readable image"},
  };
  for (const Case& c : cases) {
    const auto res = Submit(alice_, c.archive, c.what == "wrong size" ? "w" : "m");
    ASSERT_TRUE(res) << c.what;
    EXPECT_EQ(res->status, c.status) << c.what << ": " << res->body;
    const nlohmann::json body = nlohmann::json::parse(res->body);
    EXPECT_NE(body["error"].get<std::string>().find(c.reason), std::string::npos)
        << c.what << ": " << body["error"];
  }
  // Nothing but the accepted submission's folder; no incoming leftovers; nothing outside.
  std::vector<std::string> entries;
  for (const auto& entry : fs::directory_iterator(root_ / "submissions")) {
    entries.push_back(entry.path().filename().string());
  }
  EXPECT_EQ(entries.size(), 1u);
  EXPECT_FALSE(fs::exists("/tmp/00.png") && ReadFileToString("/tmp/00.png") == png);
  std::vector<std::string> top;
  for (const auto& entry : fs::directory_iterator(root_)) top.push_back(entry.path().filename());
  std::sort(top.begin(), top.end());
  EXPECT_EQ(top,
            (std::vector<std::string>{".rephoto-serve", "benchmark.sqlite", "benchmark.sqlite-shm",
                                      "benchmark.sqlite-wal", "public", "secret", "submissions"}));
  // Still serving, the accepted submission intact and scored.
  ASSERT_TRUE(server_->submissions().WaitIdle(60));
  EXPECT_EQ(Json("/api/datasets/tiny/leaderboard")["entries"].size(), 1u);
}

TEST_F(ServerTest, ARenderThatCannotBeDecodedIsScoredAsFailedWithTheReason) {
  // Its header (size) is right, so intake accepts it; decoding fails while scoring.
  const std::string png = ReadFileToString(SecretPhotoFolder(root_, "tiny") / "00.png");
  const auto res =
      Submit(alice_, MakeArchive({{"00.png", png.substr(0, png.size() / 2)}}, ArchiveFormat::kTar));
  ASSERT_EQ(res->status, 202) << res->body;
  ASSERT_TRUE(server_->submissions().WaitIdle(60));
  const nlohmann::json submission =
      Json("/api/submissions/" + nlohmann::json::parse(res->body)["id"].get<std::string>());
  EXPECT_EQ(submission["status"], "failed");
  // Named relative to the submission: no server path (issue 27, observation 7).
  const std::string reason = submission["reason"];
  EXPECT_EQ(reason.rfind("00.png: ", 0), 0u) << reason;
  EXPECT_EQ(reason.find(root_.string()), std::string::npos) << reason;
  EXPECT_EQ(reason.find("/submissions/"), std::string::npos) << reason;
  EXPECT_FALSE(submission.contains("summary"));
  EXPECT_TRUE(Json("/api/datasets/tiny/leaderboard")["entries"].empty());
}

TEST_F(ServerTest, OneServerPerRootAndUnacceptedUploadsAreRemovedOnStart) {
  ServerOptions options;
  options.port = 0;
  {
    Server second(root_, options);
    EXPECT_NE(rephoto::testing::ErrorOf([&] { second.Bind(); }).find("another rephoto serve"),
              std::string::npos);
  }
  // What a server killed in the middle of an upload leaves behind.
  const fs::path submissions = root_ / "submissions";
  fs::create_directories(submissions / ".incoming-0123" / "renders");
  fs::create_directories(submissions / std::string(32, 'a') / "renders");
  const auto accepted = Submit(alice_, testing::RendersFromPhotos(root_, "tiny", 0.0, rng_));
  ASSERT_EQ(accepted->status, 202);
  ASSERT_TRUE(server_->submissions().WaitIdle(60));
  server_->Stop();
  thread_.join();
  server_.reset();
  server_ = std::make_unique<Server>(root_, options);
  port_ = server_->Bind();
  thread_ = std::thread([this] { server_->Run(); });
  EXPECT_FALSE(fs::exists(submissions / ".incoming-0123"));
  EXPECT_FALSE(fs::exists(submissions / std::string(32, 'a')));
  const std::string id = nlohmann::json::parse(accepted->body)["id"];
  EXPECT_TRUE(fs::exists(SubmissionRunFolder(root_, id) / "summary.json"));
}

TEST_F(ServerTest, RateLimitsEachParticipantWith429) {
  StopServer();
  ServerOptions options = DefaultOptions();
  options.limits.max_per_window = 3;
  StartServer(options);
  const std::string good = testing::RendersFromPhotos(root_, "tiny", 0.0, rng_);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(Submit(bob_, good)->status, 202);
  const auto refused = Submit(bob_, good);
  EXPECT_EQ(refused->status, 429);
  EXPECT_NE(refused->body.find("at most 3 submission attempts"), std::string::npos);
  EXPECT_EQ(Submit(alice_, good)->status, 202);  // others are not affected
  ASSERT_TRUE(server_->submissions().WaitIdle(120));
}

TEST_F(ServerTest, MultipartUploadsWorkAsCurlSendsThem) {
  const std::string good = testing::RendersFromPhotos(root_, "tiny", 0.0, rng_);
  httplib::MultipartFormDataItems items = {{"archive", good, "renders.tar", "application/x-tar"},
                                           {"method", "form method", "", ""},
                                           {"description", "sent as a form", "", ""}};
  const auto res = client_->Post("/api/datasets/tiny/submissions",
                                 {{"Authorization", "Bearer " + alice_}}, items);
  ASSERT_EQ(res->status, 202) << res->body;
  const nlohmann::json submission =
      Json("/api/submissions/" + nlohmann::json::parse(res->body)["id"].get<std::string>());
  EXPECT_EQ(submission["method"], "form method");
  EXPECT_EQ(submission["description"], "sent as a form");
  // A form field longer than its limit, or with a control character, is refused.
  for (const std::string& description : {std::string(20000, 'd'), std::string("a\x01b")}) {
    httplib::MultipartFormDataItems bad = {{"archive", good, "renders.tar", "application/x-tar"},
                                           {"method", "form method", "", ""},
                                           {"description", description, "", ""}};
    const auto refused = client_->Post("/api/datasets/tiny/submissions",
                                       {{"Authorization", "Bearer " + alice_}}, bad);
    ASSERT_TRUE(refused);
    EXPECT_EQ(refused->status, 400) << refused->body;
  }
  ASSERT_TRUE(server_->submissions().WaitIdle(60));
}

}  // namespace
}  // namespace rephoto::benchmark
