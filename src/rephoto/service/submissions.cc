#include "rephoto/service/submissions.h"

#include <fmt/format.h>
#include <openssl/rand.h>

#include <chrono>
#include <cmath>
#include <map>
#include <set>

#include "rephoto/service/dataset.h"
#include "rephoto/service/text.h"
#include "rephoto/compare/compare.h"
#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/run/run_table.h"
#include "rephoto/io/image_io.h"

namespace rephoto::service {
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
  // Error images are the secret photos pixel by pixel (a flat grey render's psnr error image
  // is (photo - 0.5)^2): none is ever made.
  options.write_error_images = false;
  return options;
}

std::vector<std::string> TestStems(const DatasetRecord& dataset) {
  std::vector<std::string> stems;
  for (const auto& image : dataset.info.at("test_images")) stems.push_back(image.at("stem"));
  return stems;
}

// The leaderboard scores of every subset: "all", and with a public/private split "public" and
// "private" (without one, every photo is public).
nlohmann::json AllScores(const fs::path& per_image_csv, const DatasetRecord& dataset) {
  const nlohmann::json& settings = dataset.info.at("settings");
  std::vector<metrics::Metric> metric_list;
  for (const auto& name : settings.at("metrics")) {
    metric_list.push_back(*metrics::ParseMetric(name.get<std::string>()));
  }
  const std::vector<std::string> all = TestStems(dataset);
  std::vector<std::string> public_stems = all, private_stems;
  if (settings.contains("public_stems")) {
    public_stems = settings.at("public_stems").get<std::vector<std::string>>();
    for (const std::string& stem : all) {
      if (std::find(public_stems.begin(), public_stems.end(), stem) == public_stems.end()) {
        private_stems.push_back(stem);
      }
    }
  }
  nlohmann::json scores = {{"all", ComputeScores(per_image_csv, all, metric_list)},
                           {"public", ComputeScores(per_image_csv, public_stems, metric_list)}};
  if (!private_stems.empty()) {
    scores["private"] = ComputeScores(per_image_csv, private_stems, metric_list);
  }
  return scores;
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

double WorstValue(metrics::Metric metric) {
  switch (metric) {
    case metrics::Metric::kOneMinusNcc:
    case metrics::Metric::kCbCr:
      return 2;
    case metrics::Metric::kZssd:
      return 4;
    case metrics::Metric::kDssim:
    case metrics::Metric::kCensus:
    case metrics::Metric::kIcid:
      return 1;
    case metrics::Metric::kPsnr:
      return 0;
    case metrics::Metric::kSsim:
      return -1;
    case metrics::Metric::kLpips:
      return 1;
  }
  return NAN;
}

nlohmann::json ComputeScores(const fs::path& per_image_csv, const std::vector<std::string>& stems,
                             const std::vector<metrics::Metric>& metric_list) {
  // per_image.csv by the run folder's one reading rule (run/run_table.h).
  const run::RunTable table = run::ReadRunTable(per_image_csv);
  std::map<std::string, size_t> rows;
  const int name_column = table.Column("name");
  for (size_t r = 0; r < table.rows.size(); ++r) rows[table.Text(r, name_column)] = r;
  const int completeness_column = table.Column("completeness");
  const double photos = static_cast<double>(stems.size());
  double completeness_sum = 0;
  for (const std::string& stem : stems) {
    const auto row = rows.find(stem);
    const double c = row == rows.end() ? NAN : table.Number(row->second, completeness_column);
    if (std::isfinite(c)) completeness_sum += std::clamp(c, 0.0, 1.0);
  }
  nlohmann::json means = nlohmann::json::object(), filled = nlohmann::json::object();
  const auto json_number = [](double value) -> nlohmann::json {
    if (std::isnan(value)) return nullptr;
    if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
    return value;
  };
  for (const metrics::Metric metric : metric_list) {
    const std::string name(metrics::MetricName(metric));
    const int metric_column = table.Column(name);
    const bool psnr = metric == metrics::Metric::kPsnr;
    // psnr is filled in its squared error, whose worst is 1.
    const double worst = psnr ? 1.0 : WorstValue(metric);
    double sum = 0, filled_sum = 0;
    int count = 0;
    for (const std::string& stem : stems) {
      const auto row = rows.find(stem);
      double c = 0, v = NAN;
      if (row != rows.end()) {
        c = table.Number(row->second, completeness_column);
        v = table.Number(row->second, metric_column);
      }
      if (!std::isnan(v)) {
        sum += v;
        ++count;
      }
      if (std::isnan(v) || !std::isfinite(c)) c = 0;
      c = std::clamp(c, 0.0, 1.0);
      if (psnr) v = std::isnan(v) ? 1.0 : std::pow(10.0, -v / 10.0);
      filled_sum += c > 0 ? c * v + (1 - c) * worst : worst;
    }
    means[name] = json_number(count > 0 ? sum / count : NAN);
    const double mean_filled = photos > 0 ? filled_sum / photos : NAN;
    filled[name] = json_number(psnr ? -10.0 * std::log10(mean_filled) : mean_filled);
  }
  return {{"photos", stems.size()},
          {"completeness", json_number(photos > 0 ? completeness_sum / photos : NAN)},
          {"means", means},
          {"filled", filled}};
}

int64_t LargestRenders(const nlohmann::json& test_images) {
  int64_t total = 0;
  for (const auto& image : test_images) {
    total += int64_t{20} * image.at("width").get<int64_t>() * image.at("height").get<int64_t>() +
             (int64_t{1} << 20);
  }
  return total;
}

std::string RelativeReason(const std::string& text, const fs::path& root, const std::string& id) {
  std::string out = text;
  const auto replace_all = [&](const std::string& from, const std::string& to) {
    if (from.empty()) return;
    for (size_t at = out.find(from); at != std::string::npos; at = out.find(from, at + to.size())) {
      out.replace(at, from.size(), to);
    }
  };
  const fs::path folder = SubmissionFolder(root, id);
  for (const fs::path& base : {fs::absolute(folder), folder}) {
    replace_all((base / "renders").string() + "/", "");
    replace_all((base / "run").string() + "/", "");
    replace_all(base.string() + "/", "");
  }
  for (const fs::path& base : {fs::absolute(root), root}) {
    replace_all(base.string() + "/", "<server>/");
    replace_all(base.string(), "<server>");
  }
  return out;
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
  // Submissions scored by a server without leaderboard scores: computed from their run folder.
  for (const SubmissionRecord& record : store_.SubmissionsWithStatus({SubmissionStatus::kDone})) {
    if (!record.scores.is_null()) continue;
    try {
      const auto dataset = store_.FindDataset(record.dataset);
      REPHOTO_CHECK(dataset, "dataset '{}' is gone", record.dataset);
      store_.SetStatus(
          record.id, SubmissionStatus::kDone, "", record.summary,
          AllScores(SubmissionRunFolder(store_.root(), record.id) / "per_image.csv", *dataset));
    } catch (const std::exception& error) {
      LogWarning(fmt::format("submission {}: no leaderboard scores: {}", record.id,
                             Printable(error.what(), 1000)));
    }
  }
  for (const SubmissionRecord& record :
       store_.SubmissionsWithStatus({SubmissionStatus::kQueued, SubmissionStatus::kScoring})) {
    LogInfo(fmt::format("re-queueing submission {} ({})", record.id, StatusName(record.status)));
    Enqueue(record.id);
  }
  for (int i = 0; i < worker_count_; ++i) workers_.emplace_back([this] { Work(); });
}

Submissions::Upload& Submissions::Upload::operator=(Upload&& other) noexcept {
  if (this != &other) {
    this->~Upload();
    id_ = std::move(other.id_);
    folder_ = std::move(other.folder_);
    archive_ = std::move(other.archive_);
    other.folder_.clear();
  }
  return *this;
}

Submissions::Upload::~Upload() {
  std::error_code ignored;
  if (!folder_.empty()) fs::remove_all(folder_, ignored);
  folder_.clear();
}

nlohmann::json Submissions::Quota(const ParticipantRecord& participant) {
  const int used = store_.RecentAttempts(participant.id, limits_.window_seconds);
  return {{"limit", limits_.max_per_window},
          {"window_seconds", limits_.window_seconds},
          {"used", used},
          {"remaining", std::max(0, limits_.max_per_window - used)}};
}

Submissions::Upload Submissions::Begin(const ParticipantRecord& participant,
                                       const std::string& dataset) {
  if (!store_.FindDataset(dataset)) {
    throw Refused(404, fmt::format("no dataset named '{}'", Printable(dataset)));
  }
  if (!store_.RecordAttempt(participant.id, limits_.max_per_window, limits_.window_seconds)) {
    throw Refused(429, fmt::format("rate limit: at most {} submission attempts per {} s",
                                   limits_.max_per_window, limits_.window_seconds));
  }
  Upload upload;
  upload.id_ = NewSubmissionId();
  upload.folder_ = store_.root() / "submissions" / (".incoming-" + upload.id_);
  fs::create_directories(upload.folder_ / "renders");
  upload.archive_ = upload.folder_ / "archive";
  return upload;
}

std::string Submissions::Finish(const ParticipantRecord& participant, const std::string& dataset,
                                Upload upload, const std::string& method,
                                const std::string& description) {
  const std::optional<DatasetRecord> record = store_.FindDataset(dataset);
  if (!record) throw Refused(404, fmt::format("no dataset named '{}'", Printable(dataset)));
  CheckRequestText(method, "the method name (query parameter or field 'method')", 1, 100);
  CheckRequestText(description, "the description", 0, 10000, TextPolicy::kMultiLine);
  std::set<std::string> stems;
  for (const auto& image : record->info.at("test_images")) {
    stems.insert(image.at("stem").get<std::string>());
  }
  ArchiveLimits archive_limits = limits_.archive;
  archive_limits.max_bytes =
      std::min(archive_limits.max_bytes, LargestRenders(record->info.at("test_images")));
  const std::vector<ExtractedFile> files =
      ExtractRendersFromFile(upload.archive(), stems, archive_limits, upload.folder_ / "renders");
  if (files.empty()) throw Refused(400, "the archive holds no render");
  CheckRenderSizes(files, record->info.at("test_images"));
  fs::remove(upload.archive());

  SubmissionRecord submission;
  submission.id = upload.id();
  submission.dataset_id = record->id;
  submission.participant_id = participant.id;
  submission.method = method;
  submission.description = description;
  const fs::path folder = SubmissionFolder(store_.root(), submission.id);
  fs::rename(upload.folder_, folder);
  upload.folder_.clear();
  FolderGuard accepted{folder};
  // The attempt was counted by Begin; the row is inserted whatever the count is now.
  if (!store_.AddSubmission(submission, std::numeric_limits<int>::max(), limits_.window_seconds)) {
    ThrowError("submission {} could not be recorded", submission.id);
  }
  accepted.path.clear();
  Enqueue(submission.id);
  return submission.id;
}

std::string Submissions::Submit(const ParticipantRecord& participant, const std::string& dataset,
                                std::string_view archive, const std::string& method,
                                const std::string& description) {
  Upload upload = Begin(participant, dataset);
  WriteTextFileAtomically(upload.archive(), archive);
  return Finish(participant, dataset, std::move(upload), method, description);
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
    const nlohmann::json scores = AllScores(options.out / "per_image.csv", *dataset);
    store_.SetStatus(id, SubmissionStatus::kDone, "", summary, scores);
    LogInfo(fmt::format("submission {} scored", id));
  } catch (const std::exception& error) {
    LogWarning(fmt::format("submission {} failed: {}", id, Printable(error.what(), 1000)));
    try {
      store_.SetStatus(id, SubmissionStatus::kFailed,
                       Printable(RelativeReason(error.what(), store_.root(), id), 1000), nullptr);
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

}  // namespace rephoto::service
