// A small cache of the values made last: Get(key, make) returns the value cached for a key equal
// to `key`, or stores and returns make() (evicting the least recently used of `capacity`).
// For a few expensive, immutable tables (ray tables of the cameras used last), compared by ==:
// the lookup is a linear scan.
//
// Thread safety: Get may be called from any thread; make() runs outside the lock, so two threads
// may build the same value at once (the later one is kept; both are equal).
#pragma once

#include <cstddef>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

namespace rephoto {

template <typename Key, typename Value>
class RecentCache {
 public:
  explicit RecentCache(size_t capacity) : capacity_(capacity) {}

  template <typename Make>
  std::shared_ptr<const Value> Get(const Key& key, Make&& make) {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      for (auto it = entries_.begin(); it != entries_.end(); ++it) {
        if (it->first == key) {
          auto found = std::move(*it);
          entries_.erase(it);
          entries_.push_back(found);
          return found.second;
        }
      }
    }
    std::shared_ptr<const Value> value = std::make_shared<const Value>(make());
    std::lock_guard<std::mutex> lock(mutex_);
    if (entries_.size() >= capacity_) entries_.erase(entries_.begin());
    entries_.emplace_back(key, value);
    return value;
  }

 private:
  size_t capacity_;
  std::mutex mutex_;
  std::vector<std::pair<Key, std::shared_ptr<const Value>>> entries_;  // most recent last
};

}  // namespace rephoto
