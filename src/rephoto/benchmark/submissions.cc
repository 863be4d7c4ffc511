#include "rephoto/benchmark/submissions.h"

#include <fmt/format.h>
#include <openssl/rand.h>

#include <chrono>
#include <cmath>
#include <map>
#include <set>

#include "rephoto/benchmark/dataset.h"
#include "rephoto/compare/compare.h"
#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/io/image_io.h"

namespace rephoto::benchmark {
namespace fs = std::filesystem;
namespace {

std::string NewSubmissionId() {
  unsigned char bytes[16];
  REPHOTO_CHECK(RAND_bytes(bytes, sizeof(bytes)) == 1, "OpenSSL RAND_bytes failed");
  std::string id;
  for (unsigned char byte : bytes) id += fmt::format("{:02x}", byte);
  return id;
}

// Removes a folder on scope exit unless released.
struct FolderGuard {
  ~FolderGuard() {
    std::error_code ignored;
    if (!path.empty()) fs::remove_all(path, ignored);
  }
  fs::path path;
};

// Refuses (400) a render whose size differs from its test camera's.
void CheckRenderSizes(const std::vector<ExtractedFile>& files, const nlohmann::json& test_images) {
  std::map<std::string, std::pair<int, int>> sizes;
  for (const auto& image : test_images) {
    sizes[image.at("stem").get<std::string>()] = {image.at("width").get<int>(),
                                                  image.at("height").get<int>()};
  }
  for (const ExtractedFile& file : files) {
    io::ImageHeader header;
    try {
      header = io::ReadImageHeader(file.path);
    } catch (const Error& error) {
      throw Refused(
          400, fmt::format("render '{}': not a readable image", file.path.filename().string()));
    }
    const auto [width, height] = sizes.at(file.stem);
    if (header.width != width || header.height != height) {
      throw Refused(400, fmt::format("render '{}' is {}x{}, test camera '{}' is {}x{}",
                                     file.path.filename().string(), header.width, header.height,
                                     file.stem, width, height));
    }
  }
}

compare::CompareOptions ScoringOptions(const fs::path& root, const DatasetRecord& dataset,
                                       const std::string& id) {
  const nlohmann::json& settings = dataset.info.at("settings");
  compare::CompareOptions options;
  options.photos = SecretPhotoFolder(root, dataset.name);
  options.renders = SubmissionFolder(root, id) / "renders";
  options.out = SubmissionRunFolder(root, id);
  options.metrics.clear();
  for (const auto& name : settings.at("metrics")) {
    options.metrics.push_back(*metrics::ParseMetric(name.get<std::string>()));
  }
  options.metric_options.window = settings.at("window").get<int>();
  if (settings.value("masks", false)) options.photo_masks = SecretMaskFolder(root, dataset.name);
  return options;
}

}  // namespace

fs::path SubmissionFolder(const fs::path& root, const std::string& id) {
  return root / "submissions" / id;
}

fs::path SubmissionRunFolder(const fs::path& root, const std::string& id) {
  return SubmissionFolder(root, id) / "run";
}

bool IsSubmissionId(std::string_view id) {
  if (id.size() != 32) return false;
  for (char c : id) {
    if (!((c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'))) return false;
  }
  return true;
}

double LeaderboardCompleteness(const nlohmann::json& summary) {
  if (!summary.is_object()) return NAN;
  const auto& completeness = summary.at("completeness");
  const double photos = summary.at("counts").at("photos").get<double>();
  if (!completeness.at("mean").is_number() || photos <= 0) return 0;
  return completeness.at("mean").get<double>() * completeness.at("images").get<double>() / photos;
}

Submissions::Submissions(Store& store, SubmissionLimits limits, int workers)
    : store_(store), limits_(limits), worker_count_(std::max(1, workers)) {}

Submissions::~Submissions() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  for (std::thread& worker : workers_) worker.join();
}

// Removes what a killed server left of uploads it had not accepted: incoming folders, and
// submission folders without a database row (killed between the rename and the insert).
void RemoveUnacceptedUploads(Store& store) {
  const fs::path folder = store.root() / "submissions";
  if (!fs::is_directory(folder)) return;
  std::vector<fs::path> stale;
  for (const auto& entry : fs::directory_iterator(folder)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(".incoming-", 0) == 0 || (IsSubmissionId(name) && !store.FindSubmission(name))) {
      stale.push_back(entry.path());
    }
  }
  for (const fs::path& path : stale) {
    LogInfo(fmt::format("removing {} (an upload that was never accepted)", path.string()));
    fs::remove_all(path);
  }
}

void Submissions::Start() {
  RemoveUnacceptedUploads(store_);
  for (const SubmissionRecord& record :
       store_.SubmissionsWithStatus({SubmissionStatus::kQueued, SubmissionStatus::kScoring})) {
    LogInfo(fmt::format("re-queueing submission {} ({})", record.id, StatusName(record.status)));
    Enqueue(record.id);
  }
  for (int i = 0; i < worker_count_; ++i) workers_.emplace_back([this] { Work(); });
}

std::string Submissions::Submit(const ParticipantRecord& participant, const std::string& dataset,
                                std::string_view archive, const std::string& method,
                                const std::string& description) {
  const std::optional<DatasetRecord> record = store_.FindDataset(dataset);
  if (!record) throw Refused(404, fmt::format("no dataset named '{}'", dataset));
  if (method.empty() || method.size() > 100) {
    throw Refused(400, "the method name must be 1 to 100 bytes (query parameter 'method')");
  }
  if (description.size() > 10000) throw Refused(400, "the description exceeds 10000 bytes");
  const auto too_many = [&] {
    return Refused(429, fmt::format("rate limit: at most {} submissions per {} s",
                                    limits_.max_per_window, limits_.window_seconds));
  };
  if (store_.RecentSubmissions(participant.id, limits_.window_seconds) >= limits_.max_per_window) {
    throw too_many();
  }
  const std::string id = NewSubmissionId();
  FolderGuard incoming{store_.root() / "submissions" / (".incoming-" + id)};
  fs::create_directories(incoming.path / "renders");
  std::set<std::string> stems;
  for (const auto& image : record->info.at("test_images")) {
    stems.insert(image.at("stem").get<std::string>());
  }
  const std::vector<ExtractedFile> files =
      ExtractRenders(archive, stems, limits_.archive, incoming.path / "renders");
  if (files.empty()) throw Refused(400, "the archive holds no render");
  CheckRenderSizes(files, record->info.at("test_images"));

  SubmissionRecord submission;
  submission.id = id;
  submission.dataset_id = record->id;
  submission.participant_id = participant.id;
  submission.method = method;
  submission.description = description;
  const fs::path folder = SubmissionFolder(store_.root(), id);
  fs::rename(incoming.path, folder);
  incoming.path.clear();
  FolderGuard accepted{folder};
  if (!store_.AddSubmission(submission, limits_.max_per_window, limits_.window_seconds)) {
    throw too_many();
  }
  accepted.path.clear();
  Enqueue(id);
  return id;
}

void Submissions::Enqueue(const std::string& id) {
  {
    std::lock_guard lock(mutex_);
    queue_.push_back(id);
  }
  wake_.notify_one();
}

void Submissions::Work() {
  for (;;) {
    std::string id;
    {
      std::unique_lock lock(mutex_);
      wake_.wait(lock, [this] { return stopping_ || !queue_.empty(); });
      if (stopping_) return;
      id = queue_.front();
      queue_.pop_front();
      ++busy_;
    }
    Score(id);
    {
      std::lock_guard lock(mutex_);
      --busy_;
    }
    idle_.notify_all();
  }
}

void Submissions::Score(const std::string& id) {
  try {
    const std::optional<SubmissionRecord> submission = store_.FindSubmission(id);
    REPHOTO_CHECK(submission, "no submission '{}'", id);
    const std::optional<DatasetRecord> dataset = store_.FindDataset(submission->dataset);
    REPHOTO_CHECK(dataset, "dataset '{}' is gone", submission->dataset);
    store_.SetStatus(id, SubmissionStatus::kScoring, "", nullptr);
    const compare::CompareOptions options = ScoringOptions(store_.root(), *dataset, id);
    compare::RunCompare(options);
    const nlohmann::json summary =
        nlohmann::json::parse(ReadFileToString(options.out / "summary.json"));
    store_.SetStatus(id, SubmissionStatus::kDone, "", summary);
    LogInfo(fmt::format("submission {} scored", id));
  } catch (const std::exception& error) {
    LogWarning(fmt::format("submission {} failed: {}", id, error.what()));
    try {
      store_.SetStatus(id, SubmissionStatus::kFailed, error.what(), nullptr);
    } catch (const std::exception& again) {
      LogWarning(fmt::format("submission {}: cannot record the failure: {}", id, again.what()));
    }
  }
}

bool Submissions::WaitIdle(double timeout_seconds) {
  std::unique_lock lock(mutex_);
  return idle_.wait_for(lock, std::chrono::duration<double>(timeout_seconds),
                        [this] { return queue_.empty() && busy_ == 0; });
}

}  // namespace rephoto::benchmark
