// Input keys of `rephoto evaluate`: 64-bit XXH3 (xxHash) digests of file contents and settings,
// written as 16 lowercase hex digits. A key changes whenever anything that affects a result
// changes, so resuming can skip exactly the results whose key still matches.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <mutex>
#include <span>
#include <string>
#include <string_view>

namespace rephoto::eval {

// Streaming hash of typed values. Each Add is length- or type-delimited, so ("ab","c") and
// ("a","bc") differ.
class Hasher {
 public:
  Hasher();
  ~Hasher();
  Hasher(const Hasher&) = delete;
  Hasher& operator=(const Hasher&) = delete;

  Hasher& Add(std::string_view text);
  Hasher& Add(const char* text) { return Add(std::string_view(text)); }
  Hasher& Add(const std::string& text) { return Add(std::string_view(text)); }
  Hasher& AddInt(int64_t value);
  Hasher& AddDouble(double value);  // bit pattern (-0.0 and 0.0 differ; fine for settings)
  Hasher& AddBytes(std::span<const uint8_t> bytes);
  uint64_t Digest() const;
  std::string Hex() const;  // 16 hex digits

 private:
  void* state_;
};

std::string HexDigest(uint64_t digest);

// XXH3-64 of a file's content, streamed. Throws Error naming the file when it cannot be read.
uint64_t HashFileContent(const std::filesystem::path& path);

// File content hashes remembered by (absolute path, size, modification time), so reruns do not
// re-read large photos and models. Stored as JSON; a missing or unreadable cache file is empty.
// Thread-safe.
class FileHashCache {
 public:
  explicit FileHashCache(std::filesystem::path cache_file);
  // The content hash (hex) of `path`; throws Error naming the file when it cannot be read.
  std::string Hash(const std::filesystem::path& path);
  // Writes the cache file atomically (entries of files that still exist).
  void Save() const;

 private:
  struct Entry {
    uintmax_t size = 0;
    int64_t mtime = 0;
    std::string hash;
  };
  std::filesystem::path cache_file_;
  mutable std::mutex mutex_;
  std::map<std::string, Entry> entries_;
};

}  // namespace rephoto::eval
