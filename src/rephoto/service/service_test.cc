// The benchmark as a lab and a participant run it, through the `rephoto` CLI and a
// `rephoto serve` process on 127.0.0.1, on a real scene (OpenMVS's Sceaux Castle):
//   the lab: add-dataset (test photos 00008 and 00009 kept secret, the OpenMVS mesh published
//   as a shortcut), add-participant;
//   the participant: downloads training.tar, shortcuts.tar and test-cameras.tar, colours the
//   mesh from the training photos (`rephoto colorize`), renders the test cameras (`rephoto
//   render`) and submits the renders.
// Acceptance: the API's summary is `rephoto compare`'s summary.json on the same renders and the
// secret photos; the leaderboard lists it. Recovery: `kill -9` of the server right after four
// submissions were accepted (while it scores them), then a restart: every accepted submission
// ends `done` with the same scores, and the database passes SQLite's integrity check.
#include <fcntl.h>
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <httplib.h>  // after Eigen (see server_test.cc)
#include <signal.h>
#include <spawn.h>
#include <sqlite3.h>
#include <sys/wait.h>

#include <chrono>
#include <regex>
#include <thread>

#include "rephoto/service/store.h"
#include "rephoto/core/file.h"
#include "rephoto/testing/testing.h"

extern char** environ;

namespace rephoto::service {
namespace {
namespace fs = std::filesystem;

const fs::path kScene = rephoto::testing::SharedDataDir() / "openmvs_sceaux";
const char* const kMetrics = "1-ncc,cb+cr,dssim,psnr";

// Runs `rephoto ARGS` through the shell; returns standard output, fails the test on exit != 0.
std::string Cli(const std::string& args) {
  const fs::path out = rephoto::testing::MakeTempDir() / "out.txt";
  const std::string command = std::string(REPHOTO_CLI) + " " + args + " >'" + out.string() + "'";
  EXPECT_EQ(std::system(command.c_str()), 0) << command;
  return ReadFileToString(out);
}

void Untar(const std::string& bytes, const fs::path& folder) {
  const fs::path tar = folder.string() + ".tar";
  WriteTextFileAtomically(tar, bytes);
  fs::create_directories(folder);
  ASSERT_EQ(std::system(("tar xf '" + tar.string() + "' -C '" + folder.string() + "'").c_str()), 0);
}

// A `rephoto serve` child process on a free port (read from its log).
class ServerProcess {
 public:
  explicit ServerProcess(const fs::path& root) {
    log_ = root.parent_path() / fmt::format("serve-{}.log", ++count_);
    std::vector<std::string> args = {REPHOTO_CLI,   "serve",    "--root",
                                     root.string(), "--listen", "127.0.0.1:0"};
    std::vector<char*> argv;
    for (std::string& arg : args) argv.push_back(arg.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 2, log_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    EXPECT_EQ(posix_spawn(&pid_, REPHOTO_CLI, &actions, nullptr, argv.data(), environ), 0);
    posix_spawn_file_actions_destroy(&actions);
    const std::regex serving(R"(on http://127\.0\.0\.1:(\d+)/)");
    for (int i = 0; i < 300 && port_ == 0; ++i) {
      std::smatch match;
      const std::string text = fs::exists(log_) ? ReadFileToString(log_) : "";
      if (std::regex_search(text, match, serving)) port_ = std::stoi(match[1]);
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
    EXPECT_GT(port_, 0) << ReadFileToString(log_);
  }
  ~ServerProcess() {
    if (pid_ > 0) Signal(SIGTERM);
  }
  // Sends the signal and waits for the process; returns its wait status.
  int Signal(int signal) {
    kill(pid_, signal);
    int status = 0;
    waitpid(pid_, &status, 0);
    pid_ = 0;
    return status;
  }
  httplib::Client Client() const {
    httplib::Client client("127.0.0.1", port_);
    client.set_read_timeout(120);
    return client;
  }
  std::string Log() const { return ReadFileToString(log_); }

 private:
  static inline int count_ = 0;
  fs::path log_;
  pid_t pid_ = 0;
  int port_ = 0;
};

nlohmann::json WaitUntilScored(httplib::Client& client, const std::string& id) {
  for (int i = 0; i < 1200; ++i) {
    const auto res = client.Get(("/api/submissions/" + id).c_str());
    if (res && res->status == 200) {
      nlohmann::json json = nlohmann::json::parse(res->body);
      if (json["status"] == "done" || json["status"] == "failed") return json;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  ADD_FAILURE() << "submission " << id << " not scored within 120 s";
  return {};
}

// The summary without the server's paths, as the API gives it (api.h PublicSummary).
nlohmann::json WithoutRendersPath(nlohmann::json summary) {
  for (const char* key : {"photos", "renders", "render_masks", "photo_masks"}) {
    summary["parameters"].erase(key);
  }
  return summary;
}

class ServiceTest : public ::testing::Test {
 protected:
  // The lab's and the participant's work, once for both tests.
  static void SetUpTestSuite() {
    if (!fs::exists(kScene / "scene_mesh.ply")) return;
    work_ = rephoto::testing::MakeTempDir();
    root_ = work_ / "root";
    WriteTextFileAtomically(work_ / "train.txt",
                            "00000.jpg\n00001.jpg\n00002.jpg\n00003.jpg\n"
                            "00004.jpg\n00005.jpg\n00006.jpg\n00007.jpg\n");
    WriteTextFileAtomically(work_ / "test.txt", "00008.jpg\n00009.jpg\n");
    Cli(
        fmt::format("-q benchmark add-dataset --root '{}' --name sceaux --scene '{}' "
                    "--image-root '{}' --scheme 'lists:{},{}' --shortcut '{}' --metrics {} "
                    "--description 'Sceaux Castle'",
                    root_.string(), (kScene / "colmap_text_derived").string(),
                    (kScene / "images").string(), (work_ / "train.txt").string(),
                    (work_ / "test.txt").string(), (kScene / "scene_mesh.ply").string(), kMetrics));
    const std::string out =
        Cli(fmt::format("-q benchmark add-participant --root '{}' --name lab", root_.string()));
    token_ = out.substr(out.rfind('\n', out.size() - 2) + 1);
    token_.pop_back();
  }
  static inline fs::path work_, root_;
  static inline std::string token_;
};

TEST_F(ServiceTest, ASubmissionOfTheTrueModelScoresAsRephotoCompare) {
  REPHOTO_REQUIRE_DATA("openmvs_sceaux/scene_mesh.ply");
  ServerProcess server(root_);
  httplib::Client client = server.Client();
  const fs::path participant = work_ / "participant";
  for (const std::string name : {"training", "shortcuts", "test-cameras"}) {
    const auto res = client.Get(("/api/datasets/sceaux/" + name + ".tar").c_str());
    ASSERT_TRUE(res && res->status == 200) << name;
    Untar(res->body, participant / name);
  }
  Cli(fmt::format("-q colorize '{}' --scene '{}' --image-root '{}' --out '{}'",
                  (participant / "shortcuts/shortcuts/scene_mesh.ply").string(),
                  (participant / "training/sparse").string(),
                  (participant / "training/images").string(),
                  (participant / "model.ply").string()));
  Cli(fmt::format("-q render '{}' --scene '{}' --out '{}'", (participant / "model.ply").string(),
                  (participant / "test-cameras/sparse").string(),
                  (participant / "renders").string()));
  ASSERT_EQ(std::system(("cd '" + (participant / "renders").string() +
                         "' && tar cf ../renders.tar 00008.png 00009.png")
                            .c_str()),
            0);
  const auto posted = client.Post(
      "/api/datasets/sceaux/submissions?method=OpenMVS%20mesh&description=coloured%20mesh",
      {{"Authorization", "Bearer " + token_}}, ReadFileToString(participant / "renders.tar"),
      "application/x-tar");
  ASSERT_TRUE(posted);
  ASSERT_EQ(posted->status, 202) << posted->body;
  const std::string id = nlohmann::json::parse(posted->body)["id"];
  const nlohmann::json scored = WaitUntilScored(client, id);
  ASSERT_EQ(scored["status"], "done") << scored.dump();

  // `rephoto compare` on the participant's renders and the secret photos.
  const fs::path compare_run = work_ / "compare";
  // No error images: the server makes none (they are the secret photos pixel by pixel).
  Cli(fmt::format(
      "-q compare --photos '{}' --renders '{}' --metrics {} --no-error-images --out '{}'",
      (root_ / "secret/sceaux/photos").string(), (participant / "renders").string(), kMetrics,
      compare_run.string()));
  const nlohmann::json expected =
      nlohmann::json::parse(ReadFileToString(compare_run / "summary.json"));
  EXPECT_EQ(WithoutRendersPath(scored["summary"]), WithoutRendersPath(expected));
  EXPECT_EQ(expected["counts"]["compared"], 2);
  // A coloured mesh of the scene is a real reconstruction: neither zero nor unrelated content.
  const double ncc = expected["metrics"]["1-ncc"]["mean"];
  EXPECT_GT(ncc, 0.05);
  EXPECT_LT(ncc, 0.9);

  // Administration while the server runs: a participant added by the CLI can submit at once
  // (an empty archive: 400, not 401), and revoked by the CLI cannot (401).
  const std::string out =
      Cli(fmt::format("-q benchmark add-participant --root '{}' --name late", root_.string()));
  std::string late = out.substr(out.rfind('\n', out.size() - 2) + 1);
  late.pop_back();  // the line break
  const auto try_late = [&] {
    return client
        .Post("/api/datasets/sceaux/submissions?method=x", {{"Authorization", "Bearer " + late}},
              "", "application/x-tar")
        ->status;
  };
  EXPECT_EQ(try_late(), 400);
  Cli(fmt::format("-q benchmark revoke --root '{}' --name late", root_.string()));
  EXPECT_EQ(try_late(), 401);

  const auto board = nlohmann::json::parse(client.Get("/api/datasets/sceaux/leaderboard")->body);
  ASSERT_GE(board["entries"].size(), 1u);
  bool listed = false;
  for (const auto& entry : board["entries"]) listed |= entry["id"] == id;
  EXPECT_TRUE(listed);
  // Neither secret photo's bytes in any published download.
  for (const char* photo : {"00008.jpg", "00009.jpg"}) {
    const std::string bytes = ReadFileToString(root_ / "secret/sceaux/photos" / photo);
    for (const std::string name : {"training", "shortcuts", "test-cameras"}) {
      const auto res = client.Get(("/api/datasets/sceaux/" + name + ".tar").c_str());
      EXPECT_EQ(res->body.find(bytes.substr(bytes.size() / 2, 4096)), std::string::npos) << name;
    }
  }
  WriteTextFileAtomically(work_ / "expected_summary.json", expected.dump());
}

TEST_F(ServiceTest, EveryAcceptedSubmissionIsScoredAfterKill9AndARestart) {
  REPHOTO_REQUIRE_DATA("openmvs_sceaux/scene_mesh.ply");
  const fs::path renders = work_ / "participant" / "renders.tar";
  ASSERT_TRUE(fs::exists(renders)) << "runs after the acceptance test";
  const std::string archive = ReadFileToString(renders);
  std::vector<std::string> ids;
  {
    ServerProcess server(root_);
    httplib::Client client = server.Client();
    for (int i = 0; i < 4; ++i) {
      const auto posted =
          client.Post(fmt::format("/api/datasets/sceaux/submissions?method=again{}", i).c_str(),
                      {{"Authorization", "Bearer " + token_}}, archive, "application/x-tar");
      ASSERT_TRUE(posted && posted->status == 202);
      ids.push_back(nlohmann::json::parse(posted->body)["id"]);
    }
    const int status = server.Signal(SIGKILL);
    EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
  }
  int unfinished = 0;
  {
    Store store(root_);
    for (const std::string& id : ids) {
      unfinished += store.FindSubmission(id)->status != SubmissionStatus::kDone;
    }
  }
  // Scoring one takes about a second: the kill came before most were scored.
  EXPECT_GT(unfinished, 0);
  sqlite3* db = nullptr;
  sqlite3_open((root_ / "benchmark.sqlite").c_str(), &db);
  sqlite3_stmt* check = nullptr;
  sqlite3_prepare_v2(db, "PRAGMA integrity_check", -1, &check, nullptr);
  ASSERT_EQ(sqlite3_step(check), SQLITE_ROW);
  EXPECT_STREQ(reinterpret_cast<const char*>(sqlite3_column_text(check, 0)), "ok");
  sqlite3_finalize(check);
  sqlite3_close(db);

  ServerProcess restarted(root_);
  httplib::Client client = restarted.Client();
  const nlohmann::json expected =
      nlohmann::json::parse(ReadFileToString(work_ / "expected_summary.json"));
  for (const std::string& id : ids) {
    const nlohmann::json scored = WaitUntilScored(client, id);
    ASSERT_EQ(scored["status"], "done") << id << ": " << scored.dump();
    EXPECT_EQ(WithoutRendersPath(scored["summary"]), WithoutRendersPath(expected)) << id;
  }
  EXPECT_NE(restarted.Log().find("re-queueing submission"), std::string::npos);
}

}  // namespace
}  // namespace rephoto::service
