// The benchmark's database: datasets, the files each publishes, participants and their API
// tokens, submissions and their scores. One SQLite file, `<root>/benchmark.sqlite`.
//
// SQLite settings: WAL journal (readers never block the one writer), foreign keys on, a busy
// timeout of 10 s so that the CLI's administration commands (`rephoto benchmark ...`) and a
// running server (`rephoto serve`) can use the same file at once. The schema is a list of
// migrations (kMigrations in store.cc); `PRAGMA user_version` is how many have been applied,
// and opening a database applies the missing ones in one transaction. A database written by a
// newer rephoto (user_version above the list) is refused.
//
// Tokens: "rp<participant id>_<64 hex digits>" (32 random bytes from OpenSSL RAND_bytes). Only
// a random 16-byte salt and SHA-256(salt || token) are stored; Authenticate compares hashes in
// constant time (CRYPTO_memcmp). A token is shown once, by AddParticipant.
//
// Times are seconds since the Unix epoch (UTC) as doubles.
// Failure: every method throws rephoto::Error "<db path>: <what> (<sqlite message>)".
// Thread safety: one Store may be shared by threads (a mutex serialises its one connection);
// several Store objects, also in several processes, may open the same file.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

namespace rephoto {
class SqliteConnection;
}

namespace rephoto::service {

// A file a dataset publishes, served under /api/datasets/<dataset>/<name>.
struct PublishedFile {
  std::string name;  // URL name, e.g. "training.tar"
  std::string path;  // relative to the root folder
  std::string mime;  // Content-Type
  int64_t size = 0;  // bytes
};

struct DatasetRecord {
  int64_t id = 0;
  std::string name;
  std::string description;
  // Everything add-dataset recorded: settings (metrics, headline metric, window, ...), the
  // test images (stem, name, width, height), the training images, shortcuts (see dataset.h).
  nlohmann::json info;
  double created = 0;
};

struct ParticipantRecord {
  int64_t id = 0;
  std::string name;
  bool revoked = false;
};

enum class SubmissionStatus { kQueued, kScoring, kDone, kFailed };
std::string StatusName(SubmissionStatus status);

struct SubmissionRecord {
  std::string id;  // 32 hex digits, random
  int64_t dataset_id = 0;
  std::string dataset;  // name (filled by the readers)
  int64_t participant_id = 0;
  std::string participant;  // name (filled by the readers)
  std::string method;
  std::string description;
  SubmissionStatus status = SubmissionStatus::kQueued;
  std::string reason;      // why it failed ("" otherwise)
  nlohmann::json summary;  // the run's summary.json when done, else null
  nlohmann::json scores;   // the leaderboard scores when done (submissions.h ComputeScores)
  double created = 0;
};

// Current time, seconds since the epoch.
double NowSeconds();

class Store {
 public:
  // Opens (creating if needed) <root>/benchmark.sqlite and migrates it. `root` must exist.
  explicit Store(const std::filesystem::path& root);
  ~Store();
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  const std::filesystem::path& root() const { return root_; }
  int SchemaVersion();

  // Datasets. AddDataset throws Error when the name is taken.
  int64_t AddDataset(const std::string& name, const std::string& description,
                     const nlohmann::json& info, const std::vector<PublishedFile>& files);
  std::vector<DatasetRecord> Datasets();
  std::optional<DatasetRecord> FindDataset(const std::string& name);
  std::vector<PublishedFile> Files(int64_t dataset_id);
  std::optional<PublishedFile> FindFile(int64_t dataset_id, const std::string& name);

  // Participants. AddParticipant returns the new token (see above); throws Error when the name
  // is taken. RevokeParticipant throws Error for an unknown name.
  std::string AddParticipant(const std::string& name);
  void RevokeParticipant(const std::string& name);
  std::vector<ParticipantRecord> Participants();
  // The participant whose token this is, if it is valid and not revoked.
  std::optional<ParticipantRecord> Authenticate(const std::string& token);

  // Submissions. AddSubmission inserts `record` (status queued) unless its participant made
  // `max_per_window` or more submissions in the last `window_seconds`: then it returns false
  // and inserts nothing (the check and the insert are one transaction).
  bool AddSubmission(const SubmissionRecord& record, int max_per_window, double window_seconds);
  // How many submissions the participant made in the last `window_seconds`.
  int RecentSubmissions(int64_t participant_id, double window_seconds);
  // Records one submission attempt (accepted or not) unless the participant made
  // `max_per_window` or more in the last `window_seconds`: then returns false and records
  // nothing (one transaction). RecentAttempts counts them.
  bool RecordAttempt(int64_t participant_id, int max_per_window, double window_seconds);
  int RecentAttempts(int64_t participant_id, double window_seconds);
  // Text that is not UTF-8 in `reason` is stored as is; JSON is stored with invalid UTF-8
  // replaced (U+FFFD).
  void SetStatus(const std::string& id, SubmissionStatus status, const std::string& reason,
                 const nlohmann::json& summary, const nlohmann::json& scores = nullptr);
  std::optional<SubmissionRecord> FindSubmission(const std::string& id);
  // Submissions with one of these statuses, oldest first.
  std::vector<SubmissionRecord> SubmissionsWithStatus(const std::vector<SubmissionStatus>& any);
  // A dataset's submissions, newest first.
  std::vector<SubmissionRecord> DatasetSubmissions(int64_t dataset_id);
  // A participant's submissions, newest first.
  std::vector<SubmissionRecord> ParticipantSubmissions(int64_t participant_id);
  // Replaces a dataset's info (`rephoto benchmark reveal`); throws Error for an unknown name.
  void SetDatasetInfo(const std::string& name, const nlohmann::json& info);

 private:
  struct Statement;
  void Execute(const std::string& sql);
  void Migrate();
  std::vector<SubmissionRecord> QuerySubmissions(const std::string& where,
                                                 const std::vector<std::string>& args);

  std::filesystem::path root_;
  std::filesystem::path db_path_;
  std::unique_ptr<SqliteConnection> db_;
  std::mutex mutex_;
};

}  // namespace rephoto::service
