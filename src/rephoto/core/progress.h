// Progress display for long runs, and plain log lines.
//
// On a terminal (stderr is a tty) Progress redraws one status line: "[12/300] name 4.0% ETA
// 1m20s". Otherwise it prints one plain log line per finished item so that CI logs and batch
// schedulers keep a readable record. Thread-safe.
#pragma once

#include <chrono>
#include <mutex>
#include <string>
#include <string_view>

namespace rephoto {

// Writes "rephoto: <message>" to stderr (one line), unless logging is quiet.
void LogInfo(std::string_view message);
void LogWarning(std::string_view message);
void SetQuiet(bool quiet);

class Progress {
 public:
  Progress(std::string task, size_t total);
  ~Progress();
  // Reports that one more item (named `item`) finished.
  void Advance(std::string_view item);
  // Ends the status line (called by the destructor too).
  void Finish();

 private:
  std::mutex mutex_;
  std::string task_;
  size_t total_;
  size_t done_ = 0;
  bool terminal_;
  bool finished_ = false;
  std::chrono::steady_clock::time_point start_;
};

}  // namespace rephoto
