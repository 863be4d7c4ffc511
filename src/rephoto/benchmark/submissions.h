// Intake and background scoring of submissions (`POST /api/datasets/NAME/submissions`).
//
// Submit (called on an HTTP thread; never scores):
//   1. the dataset must exist (404); method 1..100 bytes (400);
//   2. the participant's rate limit (429): at most limits.max_per_window submissions in the
//      last limits.window_seconds, checked before extracting and again, atomically, when the
//      row is inserted;
//   3. the archive is extracted by ExtractRenders (archive.h: 400/413) into
//      <root>/submissions/.incoming-<id>/renders; every render's size (header only) must equal
//      its test camera's width x height, else 400 "render '<file>' is WxH, test camera
//      '<stem>' is WxH" (a wrong size is refused at once, not scored as failed);
//   4. the folder is renamed to <root>/submissions/<id>, the row inserted (status queued), the
//      id queued for a worker. On any refusal the incoming folder is removed.
// Scoring (worker threads): status scoring; compare::RunCompare with the dataset's secret
// photos, the submission's renders, the dataset's metrics and window, out =
// <root>/submissions/<id>/run (a `rephoto compare` run folder: per_image.csv, summary.json,
// errors/); status done with summary.json's content, or failed with the error's message.
// Missing renders are not an error: they count as not covered (see LeaderboardCompleteness).
// Recovery: Start() first removes what a killed server left of uploads it never accepted
// (submissions/.incoming-*, and submission folders without a database row), then re-queues
// every submission whose status is queued or scoring (a killed server's backlog; RunCompare
// replaces a half-written run folder), oldest first. One server per root (Server locks it).
// Thread safety: Submit and the accessors may be called from any thread.
#pragma once

#include <condition_variable>
#include <deque>
#include <filesystem>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "rephoto/benchmark/archive.h"
#include "rephoto/benchmark/store.h"

namespace rephoto::benchmark {

struct SubmissionLimits {
  ArchiveLimits archive;
  int max_per_window = 20;       // submissions per participant per window
  double window_seconds = 3600;  // the rate limit's window
};

class Submissions {
 public:
  // `workers` scoring threads (>= 1), started by Start().
  Submissions(Store& store, SubmissionLimits limits, int workers = 1);
  // Stops the workers after their current submission (which stays "scoring" in the database
  // and is re-queued by the next Start()).
  ~Submissions();
  Submissions(const Submissions&) = delete;
  Submissions& operator=(const Submissions&) = delete;

  void Start();
  // Returns the new submission's id; throws Refused (see above).
  std::string Submit(const ParticipantRecord& participant, const std::string& dataset,
                     std::string_view archive, const std::string& method,
                     const std::string& description);
  // Waits until no submission is queued or being scored, or the timeout; true if idle.
  bool WaitIdle(double timeout_seconds);
  // Scores one submission now on the calling thread (what a worker does).
  void Score(const std::string& id);

  const SubmissionLimits& limits() const { return limits_; }

 private:
  void Enqueue(const std::string& id);
  void Work();

  Store& store_;
  SubmissionLimits limits_;
  int worker_count_;
  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable idle_;
  std::deque<std::string> queue_;
  int busy_ = 0;
  bool stopping_ = false;
};

// <root>/submissions/<id> and its run folder.
std::filesystem::path SubmissionFolder(const std::filesystem::path& root, const std::string& id);
std::filesystem::path SubmissionRunFolder(const std::filesystem::path& root, const std::string& id);

// Completeness over all test photos: the summary's mean completeness over compared images
// times compared / photos (a missing render counts as 0). NaN without a summary.
double LeaderboardCompleteness(const nlohmann::json& summary);

// The id's syntax: 32 lower-case hex digits (anything else is never a submission).
bool IsSubmissionId(std::string_view id);

}  // namespace rephoto::benchmark
