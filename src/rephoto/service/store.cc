#include "rephoto/service/store.h"

#include <fmt/format.h>
#include <openssl/crypto.h>
#include <openssl/rand.h>
#include <openssl/sha.h>
#include <sqlite3.h>

#include <chrono>

#include "rephoto/core/error.h"
#include "rephoto/core/sqlite.h"

namespace rephoto::service {
namespace {

// Each entry moves the schema from version i to i + 1. Never edit an entry once released:
// append a new one.
const char* const kMigrations[] = {
    R"sql(
CREATE TABLE datasets (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  description TEXT NOT NULL,
  info TEXT NOT NULL,
  created REAL NOT NULL);
CREATE TABLE files (
  dataset_id INTEGER NOT NULL REFERENCES datasets(id) ON DELETE CASCADE,
  name TEXT NOT NULL,
  path TEXT NOT NULL,
  mime TEXT NOT NULL,
  size INTEGER NOT NULL,
  PRIMARY KEY (dataset_id, name));
CREATE TABLE participants (
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  salt BLOB NOT NULL,
  token_hash BLOB NOT NULL,
  revoked INTEGER NOT NULL DEFAULT 0,
  created REAL NOT NULL);
CREATE TABLE submissions (
  id TEXT PRIMARY KEY,
  dataset_id INTEGER NOT NULL REFERENCES datasets(id),
  participant_id INTEGER NOT NULL REFERENCES participants(id),
  method TEXT NOT NULL,
  description TEXT NOT NULL,
  status TEXT NOT NULL CHECK (status IN ('queued', 'scoring', 'done', 'failed')),
  reason TEXT NOT NULL DEFAULT '',
  summary TEXT,
  created REAL NOT NULL,
  updated REAL NOT NULL);
CREATE INDEX submissions_by_participant ON submissions(participant_id, created);
CREATE INDEX submissions_by_status ON submissions(status, created);
)sql",
    // Every submission attempt past authentication, accepted or refused (the rate limit counts
    // these), and the leaderboard scores computed at scoring time (submissions.h Scores).
    R"sql(
CREATE TABLE attempts (
  id INTEGER PRIMARY KEY,
  participant_id INTEGER NOT NULL REFERENCES participants(id),
  created REAL NOT NULL);
CREATE INDEX attempts_by_participant ON attempts(participant_id, created);
ALTER TABLE submissions ADD COLUMN scores TEXT;
)sql",
};

std::string Hex(const unsigned char* bytes, size_t size) {
  std::string out;
  for (size_t i = 0; i < size; ++i) out += fmt::format("{:02x}", bytes[i]);
  return out;
}

std::vector<unsigned char> RandomBytes(size_t size) {
  std::vector<unsigned char> bytes(size);
  REPHOTO_CHECK(RAND_bytes(bytes.data(), static_cast<int>(size)) == 1,
                "OpenSSL RAND_bytes failed: no random bytes for a token");
  return bytes;
}

std::vector<unsigned char> TokenHash(const std::vector<unsigned char>& salt,
                                     const std::string& token) {
  std::vector<unsigned char> data(salt);
  data.insert(data.end(), token.begin(), token.end());
  std::vector<unsigned char> hash(SHA256_DIGEST_LENGTH);
  SHA256(data.data(), data.size(), hash.data());
  return hash;
}

std::optional<SubmissionStatus> ParseStatus(const std::string& text) {
  if (text == "queued") return SubmissionStatus::kQueued;
  if (text == "scoring") return SubmissionStatus::kScoring;
  if (text == "done") return SubmissionStatus::kDone;
  if (text == "failed") return SubmissionStatus::kFailed;
  return std::nullopt;
}

}  // namespace

std::string StatusName(SubmissionStatus status) {
  switch (status) {
    case SubmissionStatus::kQueued:
      return "queued";
    case SubmissionStatus::kScoring:
      return "scoring";
    case SubmissionStatus::kDone:
      return "done";
    case SubmissionStatus::kFailed:
      return "failed";
  }
  return "failed";
}

double NowSeconds() {
  using namespace std::chrono;
  return duration<double>(system_clock::now().time_since_epoch()).count();
}

// A prepared statement (core/sqlite.h) whose errors name the store's database.
struct Store::Statement : SqliteStatement {
  Statement(Store* store, const std::string& sql) : SqliteStatement(*store->db_, sql) {}
};

Store::Store(const std::filesystem::path& root) : root_(root), db_path_(root / "benchmark.sqlite") {
  REPHOTO_CHECK(std::filesystem::is_directory(root), "{}: not a folder", root.string());
  db_ = std::make_unique<SqliteConnection>(
      db_path_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_FULLMUTEX, 10000);
  // A throw below closes the connection (db_ is a constructed member).
  Execute("PRAGMA journal_mode=WAL");
  Execute("PRAGMA foreign_keys=ON");
  Execute("PRAGMA synchronous=NORMAL");
  Migrate();
}

Store::~Store() = default;

void Store::Execute(const std::string& sql) { db_->Execute(sql); }

int Store::SchemaVersion() {
  std::lock_guard lock(mutex_);
  Statement statement(this, "PRAGMA user_version");
  statement.Step();
  return static_cast<int>(statement.Int(0));
}

void Store::Migrate() {
  const int latest = static_cast<int>(std::size(kMigrations));
  // IMMEDIATE takes the write lock first, so two processes opening a new file do not both
  // apply the first migration.
  SqliteTransaction transaction(*db_);
  int version = 0;
  {
    Statement statement(this, "PRAGMA user_version");
    statement.Step();
    version = static_cast<int>(statement.Int(0));
  }
  REPHOTO_CHECK(
      version <= latest,
      "{}: schema version {} is newer than this rephoto knows ({}); use a newer rephoto",
      db_path_.string(), version, latest);
  for (int i = version; i < latest; ++i) Execute(kMigrations[i]);
  if (version < latest) Execute(fmt::format("PRAGMA user_version = {}", latest));
  transaction.Commit();
}

int64_t Store::AddDataset(const std::string& name, const std::string& description,
                          const nlohmann::json& info, const std::vector<PublishedFile>& files) {
  std::lock_guard lock(mutex_);
  SqliteTransaction transaction(*db_);
  {
    Statement exists(this, "SELECT 1 FROM datasets WHERE name = ?");
    REPHOTO_CHECK(!exists.Bind(name).Step(), "{}: dataset '{}' exists already", db_path_.string(),
                  name);
  }
  Statement insert(this,
                   "INSERT INTO datasets (name, description, info, created) VALUES (?, ?, ?, ?)");
  insert.Bind(name).Bind(description).Bind(info.dump()).Bind(NowSeconds()).Step();
  const int64_t id = sqlite3_last_insert_rowid(db_->get());
  for (const PublishedFile& file : files) {
    Statement add(
        this, "INSERT INTO files (dataset_id, name, path, mime, size) VALUES (?, ?, ?, ?, ?)");
    add.Bind(id).Bind(file.name).Bind(file.path).Bind(file.mime).Bind(file.size).Step();
  }
  transaction.Commit();
  return id;
}

std::vector<DatasetRecord> Store::Datasets() {
  std::lock_guard lock(mutex_);
  Statement statement(this,
                      "SELECT id, name, description, info, created FROM datasets ORDER BY name");
  std::vector<DatasetRecord> out;
  while (statement.Step()) {
    out.push_back({statement.Int(0), statement.Text(1), statement.Text(2),
                   nlohmann::json::parse(statement.Text(3)), statement.Real(4)});
  }
  return out;
}

std::optional<DatasetRecord> Store::FindDataset(const std::string& name) {
  for (DatasetRecord& dataset : Datasets()) {
    if (dataset.name == name) return std::move(dataset);
  }
  return std::nullopt;
}

std::vector<PublishedFile> Store::Files(int64_t dataset_id) {
  std::lock_guard lock(mutex_);
  Statement statement(
      this, "SELECT name, path, mime, size FROM files WHERE dataset_id = ? ORDER BY name");
  statement.Bind(dataset_id);
  std::vector<PublishedFile> out;
  while (statement.Step()) {
    out.push_back({statement.Text(0), statement.Text(1), statement.Text(2), statement.Int(3)});
  }
  return out;
}

std::optional<PublishedFile> Store::FindFile(int64_t dataset_id, const std::string& name) {
  for (PublishedFile& file : Files(dataset_id)) {
    if (file.name == name) return std::move(file);
  }
  return std::nullopt;
}

std::string Store::AddParticipant(const std::string& name) {
  REPHOTO_CHECK(!name.empty() && name.size() <= 100, "participant name must be 1 to 100 bytes");
  std::lock_guard lock(mutex_);
  SqliteTransaction transaction(*db_);
  {
    Statement exists(this, "SELECT 1 FROM participants WHERE name = ?");
    REPHOTO_CHECK(!exists.Bind(name).Step(), "{}: participant '{}' exists already",
                  db_path_.string(), name);
  }
  const std::vector<unsigned char> salt = RandomBytes(16);
  // The row first (its id is part of the token), then the hash of the whole token.
  Statement insert(
      this, "INSERT INTO participants (name, salt, token_hash, created) VALUES (?, ?, ?, ?)");
  insert.Bind(name).Bind(salt).Bind(std::vector<unsigned char>(32, 0)).Bind(NowSeconds()).Step();
  const int64_t id = sqlite3_last_insert_rowid(db_->get());
  const std::vector<unsigned char> secret = RandomBytes(32);
  const std::string token = fmt::format("rp{}_{}", id, Hex(secret.data(), secret.size()));
  Statement update(this, "UPDATE participants SET token_hash = ? WHERE id = ?");
  update.Bind(TokenHash(salt, token)).Bind(id).Step();
  transaction.Commit();
  return token;
}

void Store::RevokeParticipant(const std::string& name) {
  std::lock_guard lock(mutex_);
  Statement statement(this, "UPDATE participants SET revoked = 1 WHERE name = ?");
  statement.Bind(name).Step();
  REPHOTO_CHECK(sqlite3_changes(db_->get()) == 1, "{}: no participant named '{}'", db_path_.string(),
                name);
}

std::vector<ParticipantRecord> Store::Participants() {
  std::lock_guard lock(mutex_);
  Statement statement(this, "SELECT id, name, revoked FROM participants ORDER BY id");
  std::vector<ParticipantRecord> out;
  while (statement.Step()) {
    out.push_back({statement.Int(0), statement.Text(1), statement.Int(2) != 0});
  }
  return out;
}

std::optional<ParticipantRecord> Store::Authenticate(const std::string& token) {
  // "rp<id>_<64 hex>": the id picks the row; everything else is only compared through the hash.
  if (token.size() > 100 || token.rfind("rp", 0) != 0) return std::nullopt;
  const size_t underscore = token.find('_');
  if (underscore == std::string::npos || underscore < 3 || underscore > 20) return std::nullopt;
  int64_t id = 0;
  for (size_t i = 2; i < underscore; ++i) {
    if (token[i] < '0' || token[i] > '9') return std::nullopt;
    id = id * 10 + (token[i] - '0');
  }
  std::lock_guard lock(mutex_);
  Statement statement(this,
                      "SELECT name, salt, token_hash, revoked FROM participants WHERE id = ?");
  statement.Bind(id);
  if (!statement.Step()) return std::nullopt;
  const std::vector<unsigned char> stored = statement.Blob(2);
  const std::vector<unsigned char> hash = TokenHash(statement.Blob(1), token);
  if (stored.size() != hash.size() || CRYPTO_memcmp(stored.data(), hash.data(), hash.size()) != 0 ||
      statement.Int(3) != 0) {
    return std::nullopt;
  }
  return ParticipantRecord{id, statement.Text(0), false};
}

bool Store::AddSubmission(const SubmissionRecord& record, int max_per_window,
                          double window_seconds) {
  std::lock_guard lock(mutex_);
  SqliteTransaction transaction(*db_);
  const double now = NowSeconds();
  Statement count(this,
                  "SELECT COUNT(*) FROM submissions WHERE participant_id = ? AND created > ?");
  count.Bind(record.participant_id).Bind(now - window_seconds).Step();
  if (count.Int(0) >= max_per_window) {
    return false;  // (rolls back)
  }
  Statement insert(
      this,
      "INSERT INTO submissions (id, dataset_id, participant_id, method, description, "
      "status, created, updated) VALUES (?, ?, ?, ?, ?, 'queued', ?, ?)");
  insert.Bind(record.id)
      .Bind(record.dataset_id)
      .Bind(record.participant_id)
      .Bind(record.method)
      .Bind(record.description)
      .Bind(now)
      .Bind(now)
      .Step();
  transaction.Commit();
  return true;
}

bool Store::RecordAttempt(int64_t participant_id, int max_per_window, double window_seconds) {
  std::lock_guard lock(mutex_);
  SqliteTransaction transaction(*db_);
  const double now = NowSeconds();
  Statement count(this, "SELECT COUNT(*) FROM attempts WHERE participant_id = ? AND created > ?");
  count.Bind(participant_id).Bind(now - window_seconds).Step();
  if (count.Int(0) >= max_per_window) {
    return false;  // (rolls back)
  }
  Statement insert(this, "INSERT INTO attempts (participant_id, created) VALUES (?, ?)");
  insert.Bind(participant_id).Bind(now).Step();
  transaction.Commit();
  return true;
}

int Store::RecentAttempts(int64_t participant_id, double window_seconds) {
  std::lock_guard lock(mutex_);
  Statement count(this, "SELECT COUNT(*) FROM attempts WHERE participant_id = ? AND created > ?");
  count.Bind(participant_id).Bind(NowSeconds() - window_seconds).Step();
  return static_cast<int>(count.Int(0));
}

int Store::RecentSubmissions(int64_t participant_id, double window_seconds) {
  std::lock_guard lock(mutex_);
  Statement count(this,
                  "SELECT COUNT(*) FROM submissions WHERE participant_id = ? AND created > ?");
  count.Bind(participant_id).Bind(NowSeconds() - window_seconds).Step();
  return static_cast<int>(count.Int(0));
}

void Store::SetStatus(const std::string& id, SubmissionStatus status, const std::string& reason,
                      const nlohmann::json& summary, const nlohmann::json& scores) {
  std::lock_guard lock(mutex_);
  Statement statement(this,
                      "UPDATE submissions SET status = ?, reason = ?, summary = ?, scores = ?, "
                      "updated = ? WHERE id = ?");
  // Invalid UTF-8 (from a file name in an exception's message) is replaced, never thrown.
  statement.Bind(StatusName(status)).Bind(reason);
  for (const nlohmann::json* json : {&summary, &scores}) {
    if (json->is_null()) {
      statement.BindNull();
    } else {
      statement.Bind(json->dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
    }
  }
  statement.Bind(NowSeconds()).Bind(id).Step();
  REPHOTO_CHECK(sqlite3_changes(db_->get()) == 1, "{}: no submission '{}'", db_path_.string(), id);
}

std::vector<SubmissionRecord> Store::QuerySubmissions(const std::string& where,
                                                      const std::vector<std::string>& args) {
  std::lock_guard lock(mutex_);
  Statement statement(
      this,
      "SELECT s.id, s.dataset_id, d.name, s.participant_id, p.name, s.method, s.description, "
      "s.status, s.reason, s.summary, s.created, s.scores FROM submissions s JOIN datasets d ON "
      "d.id = "
      "s.dataset_id JOIN participants p ON p.id = s.participant_id " +
          where);
  for (const std::string& arg : args) statement.Bind(arg);
  std::vector<SubmissionRecord> out;
  while (statement.Step()) {
    SubmissionRecord record;
    record.id = statement.Text(0);
    record.dataset_id = statement.Int(1);
    record.dataset = statement.Text(2);
    record.participant_id = statement.Int(3);
    record.participant = statement.Text(4);
    record.method = statement.Text(5);
    record.description = statement.Text(6);
    record.status = ParseStatus(statement.Text(7)).value_or(SubmissionStatus::kFailed);
    record.reason = statement.Text(8);
    // A row that does not parse (edited by hand) reads as no summary, never as an exception.
    if (!statement.IsNull(9)) {
      record.summary = nlohmann::json::parse(statement.Text(9), nullptr, false);
      if (record.summary.is_discarded()) record.summary = nullptr;
    }
    record.created = statement.Real(10);
    if (!statement.IsNull(11)) {
      record.scores = nlohmann::json::parse(statement.Text(11), nullptr, false);
      if (record.scores.is_discarded()) record.scores = nullptr;
    }
    out.push_back(std::move(record));
  }
  return out;
}

std::optional<SubmissionRecord> Store::FindSubmission(const std::string& id) {
  std::vector<SubmissionRecord> found = QuerySubmissions("WHERE s.id = ?", {id});
  if (found.empty()) return std::nullopt;
  return std::move(found.front());
}

std::vector<SubmissionRecord> Store::SubmissionsWithStatus(
    const std::vector<SubmissionStatus>& any) {
  std::string where = "WHERE s.status IN (";
  std::vector<std::string> args;
  for (SubmissionStatus status : any) {
    where += args.empty() ? "?" : ", ?";
    args.push_back(StatusName(status));
  }
  return QuerySubmissions(where + ") ORDER BY s.created, s.id", args);
}

std::vector<SubmissionRecord> Store::DatasetSubmissions(int64_t dataset_id) {
  return QuerySubmissions("WHERE s.dataset_id = ? ORDER BY s.created DESC, s.id",
                          {std::to_string(dataset_id)});
}

std::vector<SubmissionRecord> Store::ParticipantSubmissions(int64_t participant_id) {
  return QuerySubmissions("WHERE s.participant_id = ? ORDER BY s.created DESC, s.id",
                          {std::to_string(participant_id)});
}

void Store::SetDatasetInfo(const std::string& name, const nlohmann::json& info) {
  std::lock_guard lock(mutex_);
  Statement statement(this, "UPDATE datasets SET info = ? WHERE name = ?");
  statement.Bind(info.dump()).Bind(name).Step();
  REPHOTO_CHECK(sqlite3_changes(db_->get()) == 1, "{}: no dataset '{}'", db_path_.string(), name);
}

}  // namespace rephoto::service
