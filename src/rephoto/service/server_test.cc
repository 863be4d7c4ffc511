// The HTTP service end to end on 127.0.0.1 (an in-process Server on a free port): the API, the
// limits and refusals with their status codes, that no URL spelling returns a byte of a secret
// photo, and that a submission's scores (per photo, summary, leaderboard) are those of an
// independent numpy computation written from the metric definitions
// (testdata/make_expected_scores.py, which wrote testdata/expected_scores.json).
#include "rephoto/service/server.h"

#include <cmath>
#include <fstream>
#include <map>

#include "rephoto/io/image_io.h"
// Last: it includes httplib (see there).
#include "rephoto/service/server_fixture.h"

namespace rephoto::service {
namespace {
namespace fs = std::filesystem;
using testing::ArchiveFormat;
using testing::MakeArchive;
using testing::RawHttp;
using testing::ServerTest;
using Type = testing::TestEntry::Type;

// The closed-form images of testdata/make_expected_scores.py (same formulas; see there), 8-bit,
// interleaved, top row first: photos for the test stems "00" (s = 0) and "03" (s = 3).
constexpr int kFixedWidth = 64, kFixedHeight = 48;
const std::vector<std::pair<std::string, int>> kFixedStems = {{"00", 0}, {"03", 3}};

std::vector<uint8_t> FixedPhoto(int s) {
  std::vector<uint8_t> rgb(size_t{3} * kFixedWidth * kFixedHeight);
  for (int y = 0; y < kFixedHeight; ++y) {
    for (int x = 0; x < kFixedWidth; ++x) {
      for (int c = 0; c < 3; ++c) {
        int v = 40 + 2 * ((x * x + 3 * y * y + 7 * x * y + 11 * x + 5 * y + 23 * c + 37 * s) % 97);
        if (c == 0 && (7 * x + 3 * y + s) % 101 == 0) v = 255;  // saturated: invalid
        rgb[3 * (static_cast<size_t>(y) * kFixedWidth + x) + c] = static_cast<uint8_t>(v);
      }
    }
  }
  return rgb;
}

// kind "exact", "offset" or "perturbed"; RGBA (alpha 255 rendered, 0 not rendered).
std::vector<uint8_t> FixedRender(const std::string& kind, int s) {
  const std::vector<uint8_t> photo = FixedPhoto(s);
  std::vector<uint8_t> rgba(size_t{4} * kFixedWidth * kFixedHeight);
  for (int y = 0; y < kFixedHeight; ++y) {
    for (int x = 0; x < kFixedWidth; ++x) {
      const size_t pixel = static_cast<size_t>(y) * kFixedWidth + x;
      bool rendered = true;
      for (int c = 0; c < 3; ++c) {
        const int p = photo[3 * pixel + c];
        int v = p;
        if (kind == "offset") v = std::min(p + 12, 255);  // the saturated pixels stay 255
        if (kind == "perturbed") {
          v = p * 3 / 4 + 30 + (5 * x + 9 * y + 13 * c + s) % 61 - 30;
          rendered = s == 0 ? x < 40 : y >= 12;
        }
        rgba[4 * pixel + c] = static_cast<uint8_t>(v);
      }
      rgba[4 * pixel + 3] = rendered ? 255 : 0;
    }
  }
  return rgba;
}

void WriteFixedPng(const fs::path& path, const std::vector<uint8_t>& pixels, int channels) {
  io::WritePng8(path, pixels, kFixedWidth, kFixedHeight, channels);
}

// A tar of the two renders of `kind`.
std::string FixedRenders(const std::string& kind) {
  const fs::path work = rephoto::testing::MakeTempDir();
  std::vector<testing::TestEntry> entries;
  for (const auto& [stem, s] : kFixedStems) {
    const fs::path png = work / (stem + ".png");
    WriteFixedPng(png, FixedRender(kind, s), 4);
    entries.push_back({stem + ".png", ReadFileToString(png)});
  }
  return MakeArchive(entries, ArchiveFormat::kTar);
}

nlohmann::json LoadExpectedScores() {
  std::ifstream in(rephoto::testing::SourceDir() /
                   "src/rephoto/service/testdata/expected_scores.json");
  EXPECT_TRUE(in.good());
  return nlohmann::json::parse(in);
}

// The reference computes in float64 from the same float32 pixel values (v / 255); rephoto sums
// windows in double but forms per-pixel values in float, so the two differ by float rounding
// (~1e-7 relative): 1e-6 on errors in [0, 2], 1e-5 dB on PSNR.
double Tolerance(const std::string& metric) { return metric == "psnr" ? 1e-5 : 1e-6; }

// `actual` as the service writes numbers (a number, or "inf") against the reference's.
void ExpectScore(const nlohmann::json& actual, const nlohmann::json& expected, double tolerance) {
  if (expected.is_string()) {
    EXPECT_EQ(actual, expected);
    return;
  }
  ASSERT_FALSE(actual.is_null()) << "expected " << expected;
  EXPECT_NEAR(JsonNumber(actual), expected.get<double>(), tolerance);
}

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

TEST_F(ServerTest, ScoresMatchAnIndependentNumpyReferenceAndRankTheLeaderboard) {
  // A dataset of the same scene whose two test photos are the closed-form FixedPhoto images.
  const fs::path scene = base_ / "fixed-scene";
  fs::copy(base_ / "scene", scene, fs::copy_options::recursive);
  for (const auto& [stem, s] : kFixedStems) {
    WriteFixedPng(scene / "images" / (stem + ".png"), FixedPhoto(s), 3);
  }
  {
    Store store(root_);
    testing::AddTinyDataset(store, scene, "fixed");
  }
  dataset_ = "fixed";
  const nlohmann::json reference = LoadExpectedScores();
  std::map<std::string, std::string> ids;  // kind -> submission id
  const std::map<std::string, std::string> owner = {
      {"exact", alice_}, {"offset", bob_}, {"perturbed", alice_}};
  for (const std::string kind : {"exact", "offset", "perturbed"}) {
    ids[kind] = SubmitOk(owner.at(kind), FixedRenders(kind), kind);
  }
  ASSERT_TRUE(server_->submissions().WaitIdle(120));

  for (const std::string kind : {"exact", "offset", "perturbed"}) {
    SCOPED_TRACE(kind);
    const nlohmann::json& expected = reference["submissions"][kind];
    // Per-photo numbers go to the submission's own participant only.
    EXPECT_FALSE(Json("/api/submissions/" + ids[kind]).contains("images"));
    const nlohmann::json submission = Json("/api/submissions/" + ids[kind], owner.at(kind));
    ASSERT_EQ(submission["status"], "done") << submission.dump();
    EXPECT_FALSE(submission["summary"]["parameters"].contains("photos"));  // no server paths
    ASSERT_EQ(submission["images"].size(), 2u);
    for (const nlohmann::json& image : submission["images"]) {
      EXPECT_FALSE(image.contains("photo"));  // no server paths
      const std::string stem = image["name"];
      SCOPED_TRACE(stem);
      const nlohmann::json& want = expected["images"][stem];
      ExpectScore(image["completeness"], want["completeness"], 1e-12);
      for (const std::string metric : {"1-ncc", "cb+cr", "psnr"}) {
        ExpectScore(image[metric], want[metric], Tolerance(metric));
        EXPECT_EQ(JsonNumber(image[metric + "_evaluated"]),
                  want[metric + "_evaluated"].get<double>())
            << metric;
      }
    }
    const nlohmann::json& summary = submission["summary"];
    ExpectScore(summary["completeness"]["mean"], expected["summary"]["completeness"], 1e-12);
    for (const std::string metric : {"1-ncc", "cb+cr", "psnr"}) {
      SCOPED_TRACE(metric);
      ExpectScore(summary["metrics"][metric]["mean"],
                  expected["summary"]["metrics"][metric]["mean"], Tolerance(metric));
      ExpectScore(summary["metrics"][metric]["pooled"],
                  expected["summary"]["metrics"][metric]["pooled"], Tolerance(metric));
      // The leaderboard's numbers (docs/benchmark.md): mean and filled score.
      const nlohmann::json& scores = submission["scores"]["all"];
      ExpectScore(scores["means"][metric], expected["summary"]["metrics"][metric]["mean"],
                  Tolerance(metric));
      ExpectScore(scores["filled"][metric], expected["filled"][metric], Tolerance(metric));
    }
  }
  // Closed forms the reference must agree with (a check of the reference itself): renders equal
  // to the photos give zero error and full coverage; a grey offset of 12/255 leaves 1-NCC and
  // cb+cr at 0 and gives PSNR 20 log10(255/12).
  const nlohmann::json& exact = reference["submissions"]["exact"]["summary"];
  EXPECT_EQ(exact["metrics"]["1-ncc"]["mean"], 0.0);
  EXPECT_EQ(exact["metrics"]["psnr"]["mean"], "inf");
  EXPECT_EQ(exact["completeness"], 1.0);
  const nlohmann::json& offset = reference["submissions"]["offset"]["summary"]["metrics"];
  EXPECT_NEAR(offset["1-ncc"]["mean"].get<double>(), 0.0, 1e-12);
  EXPECT_NEAR(offset["cb+cr"]["mean"].get<double>(), 0.0, 1e-7);  // float32 inputs
  EXPECT_NEAR(offset["psnr"]["mean"].get<double>(), 20 * std::log10(255.0 / 12), 1e-5);
  const nlohmann::json served_exact = Json("/api/submissions/" + ids["exact"])["summary"];
  EXPECT_EQ(served_exact["metrics"]["1-ncc"]["mean"], 0.0);
  EXPECT_EQ(served_exact["metrics"]["psnr"]["mean"], "inf");
  EXPECT_EQ(served_exact["completeness"]["mean"], 1.0);

  // Ranked by the filled 1-NCC: exact (0), offset (0 up to rounding; after exact by time),
  // perturbed.
  const nlohmann::json board = Json("/api/datasets/fixed/leaderboard");
  EXPECT_EQ(board["headline"], "1-ncc");
  EXPECT_EQ(board["ranking"]["rule"], "filled");
  ASSERT_EQ(board["entries"].size(), 3u);
  EXPECT_EQ(board["entries"][0]["id"], ids["exact"]);
  EXPECT_EQ(board["entries"][0]["rank"], 1);
  EXPECT_EQ(board["entries"][0]["completeness"], 1.0);
  EXPECT_EQ(board["entries"][1]["id"], ids["offset"]);
  EXPECT_EQ(board["entries"][2]["id"], ids["perturbed"]);
  const nlohmann::json& perturbed = reference["submissions"]["perturbed"];
  ExpectScore(board["entries"][2]["headline"]["filled"], perturbed["filled"]["1-ncc"], 1e-6);
  ExpectScore(board["entries"][2]["headline"]["mean"],
              perturbed["summary"]["metrics"]["1-ncc"]["mean"], 1e-6);
  ExpectScore(board["entries"][2]["completeness"], perturbed["summary"]["completeness"], 1e-12);
  ExpectScore(board["entries"][2]["metrics"]["cb+cr"],
              perturbed["summary"]["metrics"]["cb+cr"]["mean"], 1e-6);
  const std::string noisy_id = ids["perturbed"];

  // Pages: 200 and the method names.
  for (const std::string& path : std::vector<std::string>{
           "/", "/datasets/fixed", "/datasets/fixed/leaderboard", "/submissions/" + noisy_id}) {
    const auto res = client_->Get(path.c_str());
    ASSERT_TRUE(res && res->status == 200) << path;
    EXPECT_NE(res->body.find("<!DOCTYPE html>"), std::string::npos);
  }
  EXPECT_NE(client_->Get("/datasets/fixed/leaderboard")->body.find("perturbed"), std::string::npos);
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
}  // namespace rephoto::service
