// The benchmark database: migrations, SQLite settings, tokens (hash only, constant-time check,
// revocation), the atomic rate limit and the submission state machine.
#include "rephoto/service/store.h"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <openssl/sha.h>
#include <sqlite3.h>

#include <atomic>
#include <thread>

#include "rephoto/service/test_fixture.h"
#include "rephoto/core/file.h"
#include "rephoto/testing/testing.h"

namespace rephoto::service {
namespace {
namespace fs = std::filesystem;

// One value of a query on a second, raw connection (as another process would see the file).
std::string RawQuery(const fs::path& db, const std::string& sql) {
  sqlite3* handle = nullptr;
  EXPECT_EQ(sqlite3_open_v2(db.c_str(), &handle, SQLITE_OPEN_READONLY, nullptr), SQLITE_OK);
  sqlite3_stmt* stmt = nullptr;
  EXPECT_EQ(sqlite3_prepare_v2(handle, sql.c_str(), -1, &stmt, nullptr), SQLITE_OK);
  std::string value;
  if (sqlite3_step(stmt) == SQLITE_ROW && sqlite3_column_text(stmt, 0)) {
    value = reinterpret_cast<const char*>(sqlite3_column_text(stmt, 0));
  }
  sqlite3_finalize(stmt);
  sqlite3_close(handle);
  return value;
}

SubmissionRecord Submission(const std::string& id, int64_t dataset, int64_t participant) {
  SubmissionRecord record;
  record.id = id;
  record.dataset_id = dataset;
  record.participant_id = participant;
  record.method = "m";
  return record;
}

TEST(StoreTest, MigratesOnceInWalModeWithForeignKeys) {
  const fs::path root = rephoto::testing::MakeTempDir();
  {
    Store store(root);
    EXPECT_EQ(store.SchemaVersion(), 2);
  }
  Store again(root);  // reopening applies nothing twice
  EXPECT_EQ(again.SchemaVersion(), 2);
  EXPECT_EQ(RawQuery(root / "benchmark.sqlite", "PRAGMA journal_mode"), "wal");
  EXPECT_EQ(RawQuery(root / "benchmark.sqlite",
                     "SELECT COUNT(*) FROM sqlite_master WHERE "
                     "type = 'table'"),
            "5");  // datasets, files, participants, submissions, attempts
  // Foreign keys are enforced: a submission of an unknown dataset is refused.
  const std::string token = again.AddParticipant("p");
  EXPECT_NE(rephoto::testing::ErrorOf([&] {
              again.AddSubmission(Submission("a", 42, 1), 10, 60);
            }).find("FOREIGN KEY"),
            std::string::npos);
}

TEST(StoreTest, RefusesADatabaseFromANewerRephoto) {
  const fs::path root = rephoto::testing::MakeTempDir();
  { Store store(root); }
  sqlite3* handle = nullptr;
  sqlite3_open((root / "benchmark.sqlite").c_str(), &handle);
  sqlite3_exec(handle, "PRAGMA user_version = 99", nullptr, nullptr, nullptr);
  sqlite3_close(handle);
  EXPECT_NE(
      rephoto::testing::ErrorOf([&] { Store store(root); }).find("schema version 99 is newer"),
      std::string::npos);
}

TEST(StoreTest, TokensAreStoredOnlyAsSaltedHashesAndCheckedExactly) {
  const fs::path root = rephoto::testing::MakeTempDir();
  Store store(root);
  const std::string alice = store.AddParticipant("alice");
  const std::string bob = store.AddParticipant("bob");
  ASSERT_EQ(alice.size(), std::string("rp1_").size() + 64);
  EXPECT_EQ(alice.rfind("rp1_", 0), 0u);
  EXPECT_NE(alice, bob);
  EXPECT_EQ(store.Authenticate(alice)->name, "alice");
  EXPECT_EQ(store.Authenticate(bob)->name, "bob");
  // Any change of the token fails: a digit, the id (bob's secret with alice's id), the length.
  std::string changed = alice;
  changed.back() = changed.back() == '0' ? '1' : '0';
  EXPECT_FALSE(store.Authenticate(changed));
  EXPECT_FALSE(store.Authenticate("rp1_" + bob.substr(4)));
  EXPECT_FALSE(store.Authenticate(alice + "0"));
  EXPECT_FALSE(store.Authenticate(""));
  EXPECT_FALSE(store.Authenticate("rp99_" + alice.substr(4)));
  EXPECT_FALSE(store.Authenticate("rpx_" + alice.substr(4)));
  // The stored hash is SHA-256(salt || token) (an independent computation here), and the
  // token itself is nowhere in the database file.
  const std::string salt_hex = RawQuery(root / "benchmark.sqlite",
                                        "SELECT hex(salt) FROM participants WHERE name = 'alice'");
  std::string salt;
  for (size_t i = 0; i < salt_hex.size(); i += 2) {
    salt += static_cast<char>(std::stoi(salt_hex.substr(i, 2), nullptr, 16));
  }
  const std::string data = salt + alice;
  unsigned char hash[SHA256_DIGEST_LENGTH];
  SHA256(reinterpret_cast<const unsigned char*>(data.data()), data.size(), hash);
  std::string hash_hex;
  for (unsigned char b : hash) hash_hex += fmt::format("{:02X}", b);
  EXPECT_EQ(RawQuery(root / "benchmark.sqlite",
                     "SELECT hex(token_hash) FROM participants WHERE name = 'alice'"),
            hash_hex);
  for (const auto& entry : fs::directory_iterator(root)) {
    EXPECT_EQ(ReadFileToString(entry.path()).find(alice.substr(4)), std::string::npos)
        << entry.path();
  }
  store.RevokeParticipant("alice");
  EXPECT_FALSE(store.Authenticate(alice));
  EXPECT_TRUE(store.Authenticate(bob));
  EXPECT_NE(rephoto::testing::ErrorOf([&] {
              store.RevokeParticipant("carol");
            }).find("no participant named 'carol'"),
            std::string::npos);
  EXPECT_NE(rephoto::testing::ErrorOf([&] { store.AddParticipant("bob"); }).find("exists already"),
            std::string::npos);
}

TEST(StoreTest, RateLimitIsAtomicAcrossThreadsAndStoreObjects) {
  const fs::path root = rephoto::testing::MakeTempDir();
  Store store(root);
  Store other(root);  // a second connection, as the CLI beside a server
  const int64_t dataset = store.AddDataset("d", "", {{"x", 1}}, {});
  store.AddParticipant("p");
  std::atomic<int> accepted = 0;
  std::vector<std::thread> threads;
  for (int t = 0; t < 8; ++t) {
    threads.emplace_back([&, t] {
      for (int i = 0; i < 5; ++i) {
        Store& s = t % 2 ? store : other;
        if (s.AddSubmission(Submission(fmt::format("{}-{}", t, i), dataset, 1), 7, 3600)) {
          ++accepted;
        }
      }
    });
  }
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(accepted, 7);
  EXPECT_EQ(store.RecentSubmissions(1, 3600), 7);
  EXPECT_EQ(store.RecentSubmissions(1, -1), 0);  // none in the future
}

TEST(StoreTest, SubmissionStatesAndSummaryRoundTrip) {
  const fs::path root = rephoto::testing::MakeTempDir();
  Store store(root);
  const int64_t dataset = store.AddDataset(
      "d", "desc", {{"x", 1}}, {{"training.tar", "public/d/training.tar", "application/x-tar", 5}});
  store.AddParticipant("p");
  ASSERT_TRUE(store.AddSubmission(Submission("s1", dataset, 1), 10, 60));
  ASSERT_TRUE(store.AddSubmission(Submission("s2", dataset, 1), 10, 60));
  EXPECT_EQ(store.SubmissionsWithStatus({SubmissionStatus::kQueued}).size(), 2u);
  store.SetStatus("s1", SubmissionStatus::kScoring, "", nullptr);
  store.SetStatus("s2", SubmissionStatus::kFailed, "render '00.png' is broken", nullptr);
  const auto pending =
      store.SubmissionsWithStatus({SubmissionStatus::kQueued, SubmissionStatus::kScoring});
  ASSERT_EQ(pending.size(), 1u);
  EXPECT_EQ(pending[0].id, "s1");
  store.SetStatus("s1", SubmissionStatus::kDone, "", {{"completeness", {{"mean", 0.5}}}});
  const auto s1 = store.FindSubmission("s1");
  EXPECT_EQ(s1->status, SubmissionStatus::kDone);
  EXPECT_EQ(s1->summary["completeness"]["mean"], 0.5);
  EXPECT_EQ(s1->dataset, "d");
  EXPECT_EQ(s1->participant, "p");
  EXPECT_EQ(store.FindSubmission("s2")->reason, "render '00.png' is broken");
  EXPECT_FALSE(store.FindSubmission("s3"));
  EXPECT_EQ(store.FindFile(dataset, "training.tar")->path, "public/d/training.tar");
  EXPECT_FALSE(store.FindFile(dataset, "../secret"));
  EXPECT_EQ(store.DatasetSubmissions(dataset).size(), 2u);
}

}  // namespace
}  // namespace rephoto::service
