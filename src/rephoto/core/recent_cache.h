// A small cache of the values made last: Get(key, make) returns the value cached for a key equal
// to `key`, or stores and returns make(); Find and Put do the two halves separately, for callers
// that store only some values (report/thumbnails.cc keeps no failures). It holds at most
// `capacity` values and, when `max_cost` > 0, values whose costs (given to Put) add up to at most
// `max_cost`, evicting the least recently used first; a value costing more than max_cost is not
// kept. For expensive, immutable values (ray tables of the cameras used last, report
// thumbnails), compared by ==: the lookup is a linear scan, so capacities stay in the thousands.
//
// Thread safety: every member may be called from any thread; make() runs outside the lock, so
// two threads may build the same value at once (the later one is kept; both are equal).
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
  explicit RecentCache(size_t capacity, size_t max_cost = 0)
      : capacity_(capacity), max_cost_(max_cost) {}

  template <typename Make>
  std::shared_ptr<const Value> Get(const Key& key, Make&& make) {
    if (std::shared_ptr<const Value> found = Find(key)) return found;
    std::shared_ptr<const Value> value = std::make_shared<const Value>(make());
    Put(key, value);
    return value;
  }

  // The value cached for `key` (now the most recently used), or null.
  std::shared_ptr<const Value> Find(const Key& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto it = entries_.begin(); it != entries_.end(); ++it) {
      if (it->key == key) {
        Entry found = std::move(*it);
        entries_.erase(it);
        entries_.push_back(std::move(found));
        return entries_.back().value;
      }
    }
    return nullptr;
  }

  // Stores `value` for `key` (replacing a value of an equal key), evicting as above.
  void Put(const Key& key, std::shared_ptr<const Value> value, size_t cost = 0) {
    if (max_cost_ > 0 && cost > max_cost_) return;
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto it = entries_.begin(); it != entries_.end(); ++it) {
      if (it->key == key) {
        cost_ -= it->cost;
        entries_.erase(it);
        break;
      }
    }
    while (!entries_.empty() &&
           (entries_.size() >= capacity_ || (max_cost_ > 0 && cost_ + cost > max_cost_))) {
      cost_ -= entries_.front().cost;
      entries_.erase(entries_.begin());
    }
    if (capacity_ == 0) return;
    entries_.push_back({key, std::move(value), cost});
    cost_ += cost;
  }

 private:
  struct Entry {
    Key key;
    std::shared_ptr<const Value> value;
    size_t cost;
  };
  size_t capacity_, max_cost_;
  size_t cost_ = 0;
  std::mutex mutex_;
  std::vector<Entry> entries_;  // most recent last
};

}  // namespace rephoto
