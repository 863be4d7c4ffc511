#include "rephoto/benchmark/api.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "rephoto/benchmark/submissions.h"
#include "rephoto/core/file.h"
#include "rephoto/io/csv.h"

namespace rephoto::benchmark {
namespace {

nlohmann::json Number(double value) {
  if (std::isnan(value)) return nullptr;
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  return value;
}

nlohmann::json FilesJson(Store& store, const DatasetRecord& dataset) {
  nlohmann::json files = nlohmann::json::array();
  for (const PublishedFile& file : store.Files(dataset.id)) {
    files.push_back({{"name", file.name},
                     {"url", "/api/datasets/" + dataset.name + "/" + file.name},
                     {"size", file.size}});
  }
  return files;
}

// A CSV field as JSON: empty -> null, a whole number text -> number, else the text.
nlohmann::json CsvValue(const std::string& field) {
  if (field.empty()) return nullptr;
  if (field == "inf" || field == "-inf") return field;
  char* end = nullptr;
  const double value = std::strtod(field.c_str(), &end);
  if (end == field.c_str() + field.size()) return value;
  return field;
}

nlohmann::json PerImageRows(const std::filesystem::path& csv_path) {
  nlohmann::json rows = nlohmann::json::array();
  if (!std::filesystem::exists(csv_path)) return rows;
  const auto table = io::ParseCsv(ReadFileToString(csv_path), csv_path.string());
  if (table.empty()) return rows;
  const std::vector<std::string>& header = table.front();
  for (size_t r = 1; r < table.size(); ++r) {
    nlohmann::json row = nlohmann::json::object();
    for (size_t c = 0; c < header.size() && c < table[r].size(); ++c) {
      if (header[c] == "photo" || header[c] == "render") continue;  // server paths
      row[header[c]] = header[c] == "name" || header[c] == "status" ? nlohmann::json(table[r][c])
                                                                    : CsvValue(table[r][c]);
    }
    rows.push_back(row);
  }
  return rows;
}

}  // namespace

double JsonNumber(const nlohmann::json& value) {
  if (value.is_number()) return value.get<double>();
  if (value == "inf") return std::numeric_limits<double>::infinity();
  if (value == "-inf") return -std::numeric_limits<double>::infinity();
  return std::numeric_limits<double>::quiet_NaN();
}

nlohmann::json DatasetListJson(Store& store) {
  nlohmann::json list = nlohmann::json::array();
  for (const DatasetRecord& dataset : store.Datasets()) {
    list.push_back({{"name", dataset.name},
                    {"description", dataset.description},
                    {"training_images", dataset.info.at("training_images").size()},
                    {"test_images", dataset.info.at("test_images").size()},
                    {"headline", dataset.info.at("settings").at("headline")},
                    {"files", FilesJson(store, dataset)}});
  }
  return list;
}

std::optional<nlohmann::json> DatasetJson(Store& store, const std::string& name) {
  const std::optional<DatasetRecord> dataset = store.FindDataset(name);
  if (!dataset) return std::nullopt;
  nlohmann::json json = {{"name", dataset->name}, {"description", dataset->description}};
  for (const char* key : {"scheme", "settings", "training_images", "test_images", "shortcuts"}) {
    json[key] = dataset->info.at(key);
  }
  json["files"] = FilesJson(store, *dataset);
  json["submit"] = "/api/datasets/" + dataset->name + "/submissions";
  json["leaderboard"] = "/api/datasets/" + dataset->name + "/leaderboard";
  return json;
}

std::optional<nlohmann::json> LeaderboardJson(Store& store, const std::string& name) {
  const std::optional<DatasetRecord> dataset = store.FindDataset(name);
  if (!dataset) return std::nullopt;
  const nlohmann::json& settings = dataset->info.at("settings");
  const std::string headline = settings.at("headline");
  const bool higher_is_better = settings.at("higher_is_better");
  struct Entry {
    double key;
    nlohmann::json json;
  };
  std::vector<Entry> entries;
  for (const SubmissionRecord& s : store.DatasetSubmissions(dataset->id)) {
    if (s.status != SubmissionStatus::kDone || !s.summary.is_object()) continue;
    const nlohmann::json& metric = s.summary.at("metrics").at(headline);
    const double mean = JsonNumber(metric.at("mean"));
    nlohmann::json means = nlohmann::json::object();
    for (const auto& [name, values] : s.summary.at("metrics").items())
      means[name] = values.at("mean");
    entries.push_back(
        {mean,
         {{"id", s.id},
          {"participant", s.participant},
          {"method", s.method},
          {"description", s.description},
          {"created", s.created},
          {"headline", {{"mean", metric.at("mean")}, {"median", metric.at("median")}}},
          {"completeness", Number(LeaderboardCompleteness(s.summary))},
          {"metrics", means}}});
  }
  // Best first; NaN last; ties by submission time (earlier first), kept by stable_sort.
  std::reverse(entries.begin(), entries.end());  // DatasetSubmissions is newest first
  std::stable_sort(entries.begin(), entries.end(), [&](const Entry& a, const Entry& b) {
    if (std::isnan(a.key) || std::isnan(b.key)) return !std::isnan(a.key) && std::isnan(b.key);
    return higher_is_better ? a.key > b.key : a.key < b.key;
  });
  nlohmann::json list = nlohmann::json::array();
  for (size_t i = 0; i < entries.size(); ++i) {
    entries[i].json["rank"] = i + 1;
    list.push_back(std::move(entries[i].json));
  }
  return nlohmann::json{{"dataset", dataset->name},
                        {"headline", headline},
                        {"higher_is_better", higher_is_better},
                        {"entries", list}};
}

std::optional<nlohmann::json> SubmissionJson(Store& store, const std::string& id) {
  if (!IsSubmissionId(id)) return std::nullopt;
  const std::optional<SubmissionRecord> s = store.FindSubmission(id);
  if (!s) return std::nullopt;
  nlohmann::json json = {
      {"id", s->id},         {"dataset", s->dataset},         {"participant", s->participant},
      {"method", s->method}, {"description", s->description}, {"status", StatusName(s->status)},
      {"reason", s->reason}, {"created", s->created}};
  if (s->status == SubmissionStatus::kDone) {
    json["summary"] = s->summary;
    json["completeness_over_test_photos"] = Number(LeaderboardCompleteness(s->summary));
    json["images"] = PerImageRows(SubmissionRunFolder(store.root(), id) / "per_image.csv");
  }
  return json;
}

}  // namespace rephoto::benchmark
