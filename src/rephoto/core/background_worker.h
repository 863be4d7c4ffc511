// One background thread that runs jobs in the order they were submitted.
//
// Used where a stage should overlap the next one (compare decodes the next pair while it
// compares the current one; evaluate renders the next view and writes the last view's error
// images while it compares the current one). The thread lives as long as the worker, so
// per-thread buffers (decoders', thread_local scratch) are reused from job to job.
// Submit returns a future that becomes ready when the job has run; an exception thrown by the
// job is stored in that future (get() rethrows it). The destructor runs the jobs still queued,
// then joins.
// Thread safety: Submit may be called from any thread; jobs run one at a time, in order.
#pragma once

#include <condition_variable>
#include <deque>
#include <functional>
#include <future>
#include <mutex>
#include <thread>

namespace rephoto {

class BackgroundWorker {
 public:
  BackgroundWorker() : thread_([this] { Loop(); }) {}
  ~BackgroundWorker() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    wake_.notify_one();
    thread_.join();
  }
  BackgroundWorker(const BackgroundWorker&) = delete;
  BackgroundWorker& operator=(const BackgroundWorker&) = delete;

  std::future<void> Submit(std::function<void()> job) {
    std::packaged_task<void()> task(std::move(job));
    std::future<void> done = task.get_future();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      jobs_.push_back(std::move(task));
    }
    wake_.notify_one();
    return done;
  }

 private:
  void Loop() {
    for (;;) {
      std::packaged_task<void()> task;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [this] { return stop_ || !jobs_.empty(); });
        if (jobs_.empty()) return;
        task = std::move(jobs_.front());
        jobs_.pop_front();
      }
      task();
    }
  }

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::packaged_task<void()>> jobs_;
  bool stop_ = false;
  std::thread thread_;  // last: starts after the members above exist
};

}  // namespace rephoto
