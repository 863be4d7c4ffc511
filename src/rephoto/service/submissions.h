// Intake and background scoring of submissions (`POST /api/datasets/NAME/submissions`).
//
// An upload is Begin (called on an HTTP thread before the body is read), then the archive is
// written to Upload::archive (the HTTP layer streams the body there under its byte limit), then
// Finish (never scores):
//   1. Begin: the dataset must exist (404); the participant's rate limit (429): at most
//      limits.max_per_window attempts in the last limits.window_seconds. Every attempt that
//      passes this check is recorded and counts, whatever becomes of it (a bomb, a refused
//      archive, a body cut short), so refusals are not free. Makes
//      <root>/submissions/.incoming-<id>/, removed when the Upload is destroyed unless Finish
//      accepted it;
//   2. Finish: method 1..100 bytes and description up to 10000 bytes of clean text (text.h;
//      400);
//   3. the archive is extracted by ExtractRendersFromFile (archive.h: 400/413) into
//      .incoming-<id>/renders, at most min(limits.archive.max_bytes, LargestRenders(dataset))
//      bytes (no honest submission is larger, so a bomb stops there); every render's size
//      (header only) must equal
//      its test camera's width x height, else 400 "render '<file>' is WxH, test camera
//      '<stem>' is WxH" (a wrong size is refused at once, not scored as failed);
//   4. the folder is renamed to <root>/submissions/<id>, the row inserted (status queued), the
//      id queued for a worker. On any refusal the incoming folder is removed.
// Scoring (worker threads): status scoring; compare::RunCompare with the dataset's secret
// photos, the submission's renders, the dataset's metrics and window, out =
// <root>/submissions/<id>/run (a `rephoto compare` run folder: per_image.csv, summary.json; no
// error images: they are the secret photos pixel by pixel); status done with summary.json's
// content and the leaderboard scores (ComputeScores), or failed with the error's message,
// in which the server's folders are removed (file names relative to the submission).
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

#include "rephoto/service/archive.h"
#include "rephoto/service/store.h"
#include "rephoto/metrics/metrics.h"

namespace rephoto::service {

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

  // One attempt (see above). Movable; the destructor removes the incoming folder unless
  // Finish accepted it.
  class Upload {
   public:
    Upload() = default;
    Upload(Upload&& other) noexcept { *this = std::move(other); }
    Upload& operator=(Upload&& other) noexcept;
    ~Upload();
    const std::string& id() const { return id_; }
    // Where the caller writes the archive.
    const std::filesystem::path& archive() const { return archive_; }

   private:
    friend class Submissions;
    std::string id_;
    std::filesystem::path folder_, archive_;
  };
  // Step 1 above; throws Refused (404, 429).
  Upload Begin(const ParticipantRecord& participant, const std::string& dataset);
  // Steps 2-4 with the archive written to upload.archive(); returns the submission's id; throws
  // Refused (400, 413).
  std::string Finish(const ParticipantRecord& participant, const std::string& dataset,
                     Upload upload, const std::string& method, const std::string& description);
  // Begin, the archive written from memory, Finish.
  std::string Submit(const ParticipantRecord& participant, const std::string& dataset,
                     std::string_view archive, const std::string& method,
                     const std::string& description);
  // {limit, window_seconds, used, remaining}: the participant's attempts in the window.
  nlohmann::json Quota(const ParticipantRecord& participant);
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

// The worst value a metric can take at a pixel or patch (1-ncc 2, cb+cr 2, zssd 4, dssim 1,
// census 1, icid 1, ssim -1; psnr: a squared error of 1, i.e. 0 dB): what the "filled" scores
// count an uncovered pixel as.
double WorstValue(metrics::Metric metric);

// The leaderboard scores of a scored submission, from its per_image.csv, for the test photos
// `stems` (one subset: all, the public or the private ones):
//   {"photos": N, "completeness": mean over the N photos (a missing render counts 0),
//    "means": {metric: mean over the photos with a value (as compare's summary)},
//    "filled": {metric: mean over the N photos of c * v + (1 - c) * worst}}
// where c is the photo's completeness and v its mean error (0 and worst for a missing render
// or no value); psnr is filled in its squared error (MSE = 10^(-psnr/10)) and converted back.
// So rendering less never improves a filled score: every uncovered pixel counts as the worst.
nlohmann::json ComputeScores(const std::filesystem::path& per_image_csv,
                             const std::vector<std::string>& stems,
                             const std::vector<metrics::Metric>& metrics);

// The most bytes an honest submission of the dataset's test images can extract to:
// per image 20 bytes per pixel (an uncompressed float RGBA EXR with its offset tables) + 1 MiB.
int64_t LargestRenders(const nlohmann::json& test_images);

// `text` with every occurrence of the submission's folders removed (a render's path becomes
// its file name) and of the root folder replaced by "<server>".
std::string RelativeReason(const std::string& text, const std::filesystem::path& root,
                           const std::string& id);

// The id's syntax: 32 lower-case hex digits (anything else is never a submission).
bool IsSubmissionId(std::string_view id);

}  // namespace rephoto::service
