// Thin RAII wrappers over SQLite's C API (connection, transaction, statement), shared by the benchmark's store (service/store.cc) and
// the reading and writing of COLMAP's database (live/colmap_registrar.cc). Header-only: only a
// library that includes it links SQLite (SQLite::SQLite3 in its CMake DEPS).
//
// Errors throw rephoto::Error "<where>: <what> (<SQLite's message>)", where `where` names the
// database (its path). Values are bound with SQLite's parameters, never formatted into SQL.
//
// Thread safety: a connection and its statements are used from one thread at a time (the
// store serialises with its own mutex).
#pragma once

#include <sqlite3.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "rephoto/core/error.h"

namespace rephoto {

// Runs SQL without results (PRAGMA, BEGIN, COMMIT, ...) on `db`; `where` names it in errors.
inline void SqliteExecute(sqlite3* db, const std::string& sql, const std::string& where) {
  char* message = nullptr;
  if (sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &message) != SQLITE_OK) {
    const std::string text = message ? message : "unknown error";
    sqlite3_free(message);
    ThrowError("{}: {} (while running: {})", where, text, sql.substr(0, 60));
  }
}

// An open database; closed on destruction.
class SqliteConnection {
 public:
  // `flags`: SQLITE_OPEN_READONLY, SQLITE_OPEN_READWRITE [| SQLITE_OPEN_CREATE], ... Waits up
  // to `busy_ms` for another writer's lock.
  SqliteConnection(const std::filesystem::path& path, int flags, int busy_ms = 5000)
      : where_(path.string()) {
    if (sqlite3_open_v2(where_.c_str(), &db_, flags, nullptr) != SQLITE_OK) {
      const std::string message = db_ ? sqlite3_errmsg(db_) : "out of memory";
      sqlite3_close(db_);
      ThrowError("{}: cannot open the database ({})", where_, message);
    }
    sqlite3_busy_timeout(db_, busy_ms);
  }
  ~SqliteConnection() { sqlite3_close(db_); }
  SqliteConnection(const SqliteConnection&) = delete;
  SqliteConnection& operator=(const SqliteConnection&) = delete;

  sqlite3* get() const { return db_; }
  const std::string& where() const { return where_; }

  void Execute(const std::string& sql) { SqliteExecute(db_, sql, where_); }

 private:
  std::string where_;
  sqlite3* db_ = nullptr;
};

// A write transaction: BEGIN IMMEDIATE on construction (the write lock first, so two writers
// cannot both read and then write); Commit() ends it. Destroyed without a successful Commit()
// (an exception, an early return) it rolls back. Statements declared after it are finalised
// before that rollback.
class SqliteTransaction {
 public:
  SqliteTransaction(sqlite3* db, std::string where) : db_(db), where_(std::move(where)) {
    SqliteExecute(db_, "BEGIN IMMEDIATE", where_);
  }
  explicit SqliteTransaction(const SqliteConnection& db) : SqliteTransaction(db.get(), db.where()) {}
  ~SqliteTransaction() {
    if (!committed_) sqlite3_exec(db_, "ROLLBACK", nullptr, nullptr, nullptr);
  }
  SqliteTransaction(const SqliteTransaction&) = delete;
  SqliteTransaction& operator=(const SqliteTransaction&) = delete;

  void Commit() {
    SqliteExecute(db_, "COMMIT", where_);
    committed_ = true;
  }

 private:
  sqlite3* db_;
  std::string where_;
  bool committed_ = false;
};

// A prepared statement with positional text/int/real/blob binding; finalised on destruction.
class SqliteStatement {
 public:
  SqliteStatement(sqlite3* db, const std::string& sql, std::string where)
      : db_(db), where_(std::move(where)) {
    if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &stmt_, nullptr) != SQLITE_OK)
      Fail("cannot prepare a statement");
  }
  SqliteStatement(const SqliteConnection& db, const std::string& sql)
      : SqliteStatement(db.get(), sql, db.where()) {}
  ~SqliteStatement() { sqlite3_finalize(stmt_); }
  SqliteStatement(const SqliteStatement&) = delete;
  SqliteStatement& operator=(const SqliteStatement&) = delete;

  SqliteStatement& Bind(const std::string& text) {
    sqlite3_bind_text(stmt_, ++index_, text.data(), static_cast<int>(text.size()),
                      SQLITE_TRANSIENT);
    return *this;
  }
  SqliteStatement& Bind(int64_t value) {
    sqlite3_bind_int64(stmt_, ++index_, value);
    return *this;
  }
  SqliteStatement& Bind(double value) {
    sqlite3_bind_double(stmt_, ++index_, value);
    return *this;
  }
  SqliteStatement& Bind(const std::vector<unsigned char>& blob) {
    sqlite3_bind_blob(stmt_, ++index_, blob.data(), static_cast<int>(blob.size()),
                      SQLITE_TRANSIENT);
    return *this;
  }
  SqliteStatement& BindNull() {
    sqlite3_bind_null(stmt_, ++index_);
    return *this;
  }
  // True while there is a row; false when done; throws on an error.
  bool Step() {
    const int rc = sqlite3_step(stmt_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    Fail("query failed");
  }
  std::string Text(int column) const {
    const auto* text = sqlite3_column_text(stmt_, column);
    return text ? std::string(reinterpret_cast<const char*>(text),
                              static_cast<size_t>(sqlite3_column_bytes(stmt_, column)))
                : std::string();
  }
  int64_t Int(int column) const { return sqlite3_column_int64(stmt_, column); }
  double Real(int column) const { return sqlite3_column_double(stmt_, column); }
  std::vector<unsigned char> Blob(int column) const {
    const auto* data = static_cast<const unsigned char*>(sqlite3_column_blob(stmt_, column));
    return std::vector<unsigned char>(data, data + sqlite3_column_bytes(stmt_, column));
  }
  bool IsNull(int column) const { return sqlite3_column_type(stmt_, column) == SQLITE_NULL; }

 private:
  [[noreturn]] void Fail(const std::string& what) const {
    ThrowError("{}: {} ({})", where_, what, sqlite3_errmsg(db_));
  }

  sqlite3* db_;
  std::string where_;
  sqlite3_stmt* stmt_ = nullptr;
  int index_ = 0;
};

}  // namespace rephoto
