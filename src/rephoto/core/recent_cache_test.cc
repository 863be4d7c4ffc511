#include "rephoto/core/recent_cache.h"

#include <gtest/gtest.h>

#include <string>

namespace rephoto {
namespace {

using Cache = RecentCache<int, std::string>;

TEST(RecentCache, GetMakesOnceAndEvictsTheLeastRecentlyUsed) {
  Cache cache(2);
  int made = 0;
  const auto make = [&](const std::string& v) {
    return [&made, v] {
      ++made;
      return v;
    };
  };
  EXPECT_EQ(*cache.Get(1, make("a")), "a");
  EXPECT_EQ(*cache.Get(2, make("b")), "b");
  EXPECT_EQ(*cache.Get(1, make("x")), "a");  // cached: 1 is now the most recent
  EXPECT_EQ(made, 2);
  EXPECT_EQ(*cache.Get(3, make("c")), "c");  // evicts 2, the least recently used
  EXPECT_EQ(cache.Find(2), nullptr);
  ASSERT_NE(cache.Find(1), nullptr);
  EXPECT_EQ(*cache.Find(3), "c");
}

TEST(RecentCache, CostsBoundWhatIsKept) {
  Cache cache(10, 100);
  cache.Put(1, std::make_shared<const std::string>("a"), 40);
  cache.Put(2, std::make_shared<const std::string>("b"), 40);
  ASSERT_NE(cache.Find(1), nullptr);                           // 2 is now the least recently used
  cache.Put(3, std::make_shared<const std::string>("c"), 40);  // 120 > 100: 2 goes
  EXPECT_EQ(cache.Find(2), nullptr);
  EXPECT_NE(cache.Find(1), nullptr);
  EXPECT_NE(cache.Find(3), nullptr);
  cache.Put(4, std::make_shared<const std::string>("d"), 101);  // more than the bound alone
  EXPECT_EQ(cache.Find(4), nullptr);
  EXPECT_NE(cache.Find(1), nullptr);  // and nothing was evicted for it
  // Replacing a key frees its old cost: 1 (40) and the new 3 (60) make 100, both kept.
  cache.Put(3, std::make_shared<const std::string>("C"), 60);
  EXPECT_EQ(*cache.Find(3), "C");
  EXPECT_NE(cache.Find(1), nullptr);
}

}  // namespace
}  // namespace rephoto
