#include "rephoto/core/parallel.h"

#include <gtest/gtest.h>

#include <vector>

namespace rephoto {
namespace {

TEST(Parallel, ForVisitsEveryIndexOnce) {
  std::vector<int> hits(1003, 0);
  ParallelFor(0, 1003, 10, [&](int64_t b, int64_t e) {
    for (int64_t i = b; i < e; ++i) hits[i]++;
  });
  for (int h : hits) EXPECT_EQ(h, 1);
}

TEST(Parallel, SumIsIdenticalForAnyThreadCount) {
  auto sum = [] {
    return ParallelSum<double>(0, 100000, 333, [](int64_t b, int64_t e) {
      double s = 0;
      for (int64_t i = b; i < e; ++i) s += 1.0 / (1.0 + static_cast<double>(i));
      return s;
    });
  };
  double one_thread;
  {
    ThreadLimit limit(1);
    one_thread = sum();
  }
  EXPECT_EQ(one_thread, sum());  // bit-for-bit
}

}  // namespace
}  // namespace rephoto
