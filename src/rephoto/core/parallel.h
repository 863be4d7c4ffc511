// Deterministic parallelism over index ranges (TBB underneath).
//
// ParallelFor splits [begin, end) into chunks of `grain` indices and calls fn(chunk_begin,
// chunk_end) for each, possibly concurrently; fn must only write outputs owned by its chunk.
// ParallelSum computes per-chunk partial results and adds them in chunk order, so the result
// is bit-for-bit identical for any thread count (chunks depend on `grain`, not on threads).
// ParallelInvoke runs independent tasks, possibly concurrently, and returns when all are done;
// an exception thrown by a task reaches the caller (the first one, when several throw).
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/partitioner.h>

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

namespace rephoto {

template <typename Fn>
void ParallelFor(int64_t begin, int64_t end, int64_t grain, Fn&& fn) {
  if (end <= begin) return;
  grain = std::max<int64_t>(grain, 1);
  const int64_t chunks = (end - begin + grain - 1) / grain;
  if (chunks == 1) {
    fn(begin, end);
    return;
  }
  tbb::parallel_for(
      tbb::blocked_range<int64_t>(0, chunks, 1),
      [&](const tbb::blocked_range<int64_t>& r) {
        for (int64_t chunk = r.begin(); chunk != r.end(); ++chunk) {
          const int64_t b = begin + chunk * grain;
          fn(b, std::min(end, b + grain));
        }
      },
      tbb::simple_partitioner());
}

// Result fn(chunk_begin, chunk_end) for each chunk, combined as
// partial[0] + partial[1] + ... in chunk order. Result needs operator+= and value init.
template <typename Result, typename Fn>
Result ParallelSum(int64_t begin, int64_t end, int64_t grain, Fn&& fn) {
  if (end <= begin) return Result{};
  grain = std::max<int64_t>(grain, 1);
  const int64_t chunks = (end - begin + grain - 1) / grain;
  std::vector<Result> partial(static_cast<size_t>(chunks));
  ParallelFor(0, chunks, 1, [&](int64_t cb, int64_t ce) {
    for (int64_t chunk = cb; chunk < ce; ++chunk) {
      const int64_t b = begin + chunk * grain;
      partial[static_cast<size_t>(chunk)] = fn(b, std::min(end, b + grain));
    }
  });
  Result total = partial[0];
  for (size_t i = 1; i < partial.size(); ++i) total += partial[i];
  return total;
}

// Runs fns... (at least two), possibly concurrently; each must only write what it owns.
template <typename... Fns>
void ParallelInvoke(Fns&&... fns) {
  tbb::parallel_invoke(std::forward<Fns>(fns)...);
}

// Limits the number of worker threads while alive (0 = all cores).
class ThreadLimit {
 public:
  explicit ThreadLimit(int threads);
  ~ThreadLimit();
  ThreadLimit(const ThreadLimit&) = delete;
  ThreadLimit& operator=(const ThreadLimit&) = delete;

 private:
  void* control_ = nullptr;
};

}  // namespace rephoto
