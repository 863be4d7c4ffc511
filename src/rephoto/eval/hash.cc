#include "rephoto/eval/hash.h"

#include <xxhash.h>

#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"

namespace rephoto::eval {
namespace fs = std::filesystem;

namespace {
XXH3_state_t* State(void* state) { return static_cast<XXH3_state_t*>(state); }
}  // namespace

Hasher::Hasher() : state_(XXH3_createState()) {
  REPHOTO_CHECK(state_ != nullptr, "xxHash: out of memory");
  XXH3_64bits_reset(State(state_));
}
Hasher::~Hasher() { XXH3_freeState(State(state_)); }

Hasher& Hasher::Add(std::string_view text) {
  AddInt(static_cast<int64_t>(text.size()));
  XXH3_64bits_update(State(state_), text.data(), text.size());
  return *this;
}

Hasher& Hasher::AddInt(int64_t value) {
  XXH3_64bits_update(State(state_), &value, sizeof(value));
  return *this;
}

Hasher& Hasher::AddDouble(double value) {
  uint64_t bits = 0;
  std::memcpy(&bits, &value, sizeof(bits));
  return AddInt(static_cast<int64_t>(bits));
}

Hasher& Hasher::AddBytes(std::span<const uint8_t> bytes) {
  AddInt(static_cast<int64_t>(bytes.size()));
  XXH3_64bits_update(State(state_), bytes.data(), bytes.size());
  return *this;
}

uint64_t Hasher::Digest() const { return XXH3_64bits_digest(State(state_)); }

std::string Hasher::Hex() const { return HexDigest(Digest()); }

std::string HexDigest(uint64_t digest) { return fmt::format("{:016x}", digest); }

uint64_t HashFileContent(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  REPHOTO_CHECK(in.good(), "{}: cannot open for reading", path.string());
  XXH3_state_t* state = XXH3_createState();
  REPHOTO_CHECK(state != nullptr, "xxHash: out of memory");
  XXH3_64bits_reset(state);
  std::vector<char> buffer(1 << 20);
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    const std::streamsize n = in.gcount();
    if (n > 0) XXH3_64bits_update(state, buffer.data(), static_cast<size_t>(n));
  }
  const bool failed = in.bad();
  const uint64_t digest = XXH3_64bits_digest(state);
  XXH3_freeState(state);
  REPHOTO_CHECK(!failed, "{}: read error", path.string());
  return digest;
}

FileHashCache::FileHashCache(fs::path cache_file) : cache_file_(std::move(cache_file)) {
  std::error_code ec;
  if (!fs::exists(cache_file_, ec)) return;
  try {
    const nlohmann::json json = nlohmann::json::parse(ReadFileToString(cache_file_));
    for (const auto& [path, entry] : json.at("files").items()) {
      entries_[path] = {entry.at("size").get<uintmax_t>(), entry.at("mtime").get<int64_t>(),
                        entry.at("hash").get<std::string>()};
    }
  } catch (const std::exception&) {
    entries_.clear();  // a damaged cache only costs re-hashing
  }
}

std::string FileHashCache::Hash(const fs::path& path) {
  std::error_code ec;
  const fs::path absolute = fs::absolute(path, ec).lexically_normal();
  const uintmax_t size = fs::file_size(absolute, ec);
  REPHOTO_CHECK(!ec, "{}: cannot read: {}", path.string(), ec.message());
  const int64_t mtime =
      static_cast<int64_t>(fs::last_write_time(absolute, ec).time_since_epoch().count());
  REPHOTO_CHECK(!ec, "{}: cannot read: {}", path.string(), ec.message());
  {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto it = entries_.find(absolute.string());
    if (it != entries_.end() && it->second.size == size && it->second.mtime == mtime) {
      return it->second.hash;
    }
  }
  const std::string hash = HexDigest(HashFileContent(absolute));
  std::lock_guard<std::mutex> lock(mutex_);
  entries_[absolute.string()] = {size, mtime, hash};
  return hash;
}

void FileHashCache::Save() const {
  nlohmann::ordered_json json;
  json["schema"] = "rephoto.file-hashes/1";
  json["files"] = nlohmann::ordered_json::object();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    for (const auto& [path, entry] : entries_) {
      std::error_code ec;
      if (!fs::exists(path, ec)) continue;
      json["files"][path] = {{"size", entry.size}, {"mtime", entry.mtime}, {"hash", entry.hash}};
    }
  }
  WriteTextFileAtomically(cache_file_, json.dump(1) + "\n");
}

}  // namespace rephoto::eval
