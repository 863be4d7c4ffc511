#include "rephoto/service/api.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <variant>

#include "rephoto/service/submissions.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/run/run_table.h"

namespace rephoto::service {
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

nlohmann::json PerImageRows(const std::filesystem::path& csv_path) {
  nlohmann::json rows = nlohmann::json::array();
  if (!std::filesystem::exists(csv_path)) return rows;
  // per_image.csv by the run folder's one reading rule (run/run_table.h): text as text,
  // counts as integers, measurements as numbers (NaN -> null, infinities as "inf"/"-inf").
  const run::RunTable table = run::ReadRunTable(csv_path);
  for (const std::vector<run::Cell>& cells : table.rows) {
    nlohmann::json row = nlohmann::json::object();
    for (size_t c = 0; c < table.columns.size(); ++c) {
      const std::string& column = table.columns[c];
      if (column == "photo" || column == "render") continue;  // server paths
      if (const auto* text = std::get_if<std::string>(&cells[c])) {
        row[column] = *text;
      } else if (const auto* integer = std::get_if<int64_t>(&cells[c])) {
        row[column] = *integer;
      } else {
        const double value = std::get<double>(cells[c]);
        row[column] = std::isnan(value)   ? nlohmann::json(nullptr)
                      : std::isinf(value) ? nlohmann::json(value > 0 ? "inf" : "-inf")
                                          : nlohmann::json(value);
      }
    }
    rows.push_back(std::move(row));
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
  const RankingRule rule = DatasetRankingRule(*dataset);
  json["ranking"] = {{"rule", rule.text},
                     {"text", RankingRuleText(rule, dataset->info.at("settings").at("headline"))}};
  json["settings"].erase("public_stems");
  json["split"] = {{"public", TestPhotoCount(*dataset, "public")},
                   {"private", TestPhotoCount(*dataset, "private")},
                   {"revealed", dataset->info.value("revealed", false)}};
  json["files"] = FilesJson(store, *dataset);
  json["submit"] = "/api/datasets/" + dataset->name + "/submissions";
  json["leaderboard"] = "/api/datasets/" + dataset->name + "/leaderboard";
  return json;
}

RankingRule ParseRankingRule(const std::string& text) {
  RankingRule rule;
  rule.text = text;
  if (text == "filled") return rule;
  const std::string prefix = "min-completeness:";
  if (text.rfind(prefix, 0) == 0) {
    const std::string number = text.substr(prefix.size());
    char* end = nullptr;
    const double value = std::strtod(number.c_str(), &end);
    if (!number.empty() && end == number.c_str() + number.size() && value > 0 && value <= 1) {
      rule.min_completeness = value;
      return rule;
    }
  }
  throw UsageError(fmt::format(
      "--ranking '{}': expected 'filled' or 'min-completeness:F' with 0 < F <= 1", text));
}

std::string RankingRuleText(const RankingRule& rule, const std::string& headline) {
  if (rule.min_completeness) {
    return fmt::format(
        "ranked by the mean {} over the test photos among submissions whose completeness is at "
        "least {}; the others are listed below, unranked",
        headline, *rule.min_completeness);
  }
  return fmt::format(
      "ranked by {} with every pixel not rendered counted at the metric's worst value "
      "(\"filled\": per photo, completeness x mean + (1 - completeness) x worst; a missing render "
      "counts as all worst), so rendering less never ranks higher",
      headline);
}

RankingRule DatasetRankingRule(const DatasetRecord& dataset) {
  return ParseRankingRule(dataset.info.at("settings").value("ranking", std::string("filled")));
}

std::optional<nlohmann::json> LeaderboardJson(Store& store, const std::string& name,
                                              const LeaderboardOptions& options) {
  const std::optional<DatasetRecord> dataset = store.FindDataset(name);
  if (!dataset) return std::nullopt;
  const nlohmann::json& settings = dataset->info.at("settings");
  const std::string headline = settings.at("headline");
  const bool higher_is_better = settings.at("higher_is_better");
  const RankingRule rule = DatasetRankingRule(*dataset);
  const bool split = settings.contains("public_stems");
  const bool revealed = dataset->info.value("revealed", false);
  // Before the reveal the public photos rank; after it the private ones (never tuned against).
  const std::string subset = !split ? "all" : revealed ? "private" : "public";
  struct Entry {
    double key;
    bool ranked;
    std::string best_key;  // participant and method
    nlohmann::json json;
  };
  std::vector<Entry> entries;
  for (const SubmissionRecord& s : store.DatasetSubmissions(dataset->id)) {
    if (s.status != SubmissionStatus::kDone || !s.scores.is_object() ||
        !s.scores.contains(subset)) {
      continue;
    }
    // A row edited by hand (or damaged) is left out, never fails the leaderboard.
    try {
      const nlohmann::json& scores = s.scores.at(subset);
      const double completeness = JsonNumber(scores.value("completeness", nlohmann::json()));
      const nlohmann::json mean = scores.at("means").value(headline, nlohmann::json());
      const nlohmann::json filled = scores.at("filled").value(headline, nlohmann::json());
      const bool ranked = !rule.min_completeness || completeness >= *rule.min_completeness;
      nlohmann::json json = {{"id", s.id},
                             {"participant", s.participant},
                             {"method", s.method},
                             {"description", s.description},
                             {"created", s.created},
                             {"headline", {{"mean", mean}, {"filled", filled}}},
                             {"completeness", Number(completeness)},
                             {"metrics", scores.at("means")},
                             {"filled", scores.at("filled")}};
      if (split && revealed) json["public"] = s.scores.value("public", nlohmann::json());
      entries.push_back({JsonNumber(rule.min_completeness ? mean : filled), ranked,
                         std::to_string(s.participant_id) + "\n" + s.method, std::move(json)});
    } catch (const std::exception& error) {
      LogWarning(fmt::format("submission {}: left out of the leaderboard: {}", s.id, error.what()));
    }
  }
  // Best first; NaN last; ties by submission time (earlier first), kept by stable_sort.
  std::reverse(entries.begin(), entries.end());  // DatasetSubmissions is newest first
  std::stable_sort(entries.begin(), entries.end(), [&](const Entry& a, const Entry& b) {
    if (std::isnan(a.key) || std::isnan(b.key)) return !std::isnan(a.key) && std::isnan(b.key);
    return higher_is_better ? a.key > b.key : a.key < b.key;
  });
  nlohmann::json list = nlohmann::json::array(), unranked = nlohmann::json::array();
  // Best per participant and method, among the ranked and (apart) among the unranked, so an
  // unranked submission never hides a ranked one.
  std::set<std::string> shown_ranked, shown_unranked;
  for (Entry& entry : entries) {
    std::set<std::string>& shown = entry.ranked ? shown_ranked : shown_unranked;
    if (!options.all_submissions && !shown.insert(entry.best_key).second) continue;
    if (entry.ranked) {
      entry.json["rank"] = list.size() + 1;
      list.push_back(std::move(entry.json));
    } else {
      unranked.push_back(std::move(entry.json));
    }
  }
  return nlohmann::json{
      {"dataset", dataset->name},
      {"headline", headline},
      {"higher_is_better", higher_is_better},
      {"ranking", {{"rule", rule.text}, {"text", RankingRuleText(rule, headline)}}},
      {"photos", {{"subset", subset}, {"count", TestPhotoCount(*dataset, subset)}}},
      {"revealed", revealed},
      {"best_per_method", !options.all_submissions},
      {"entries", list},
      {"unranked", unranked}};
}

size_t TestPhotoCount(const DatasetRecord& dataset, const std::string& subset) {
  const nlohmann::json& settings = dataset.info.at("settings");
  const size_t all = dataset.info.at("test_images").size();
  if (!settings.contains("public_stems")) return subset == "private" ? 0 : all;
  if (subset == "all") return all;
  const size_t public_count = settings.at("public_stems").size();
  return subset == "public" ? public_count : all - public_count;
}

nlohmann::json PublicSummary(const nlohmann::json& summary) {
  nlohmann::json out = summary;
  if (out.is_object() && out.contains("parameters") && out["parameters"].is_object()) {
    for (const char* key : {"photos", "renders", "render_masks", "photo_masks"}) {
      out["parameters"].erase(key);
    }
  }
  return out;
}

std::optional<nlohmann::json> SubmissionJson(Store& store, const std::string& id,
                                             const std::optional<ParticipantRecord>& viewer) {
  if (!IsSubmissionId(id)) return std::nullopt;
  const std::optional<SubmissionRecord> s = store.FindSubmission(id);
  if (!s) return std::nullopt;
  nlohmann::json json = {
      {"id", s->id},         {"dataset", s->dataset},         {"participant", s->participant},
      {"method", s->method}, {"description", s->description}, {"status", StatusName(s->status)},
      {"reason", s->reason}, {"created", s->created}};
  if (s->status != SubmissionStatus::kDone) return json;
  const auto dataset = store.FindDataset(s->dataset);
  if (!dataset) return json;
  const nlohmann::json& settings = dataset->info.at("settings");
  const bool split = settings.contains("public_stems");
  const bool revealed = dataset->info.value("revealed", false);
  if (!split || revealed) {
    // compare's summary covers every test photo: shown once nothing is hidden.
    json["summary"] = PublicSummary(s->summary);
    json["completeness_over_test_photos"] = Number(LeaderboardCompleteness(s->summary));
  }
  if (s->scores.is_object()) {
    nlohmann::json scores = nlohmann::json::object();
    for (const char* subset : {"all", "public", "private"}) {
      if (!s->scores.contains(subset)) continue;
      if (split && !revealed && std::string(subset) != "public") continue;
      if (!split && std::string(subset) == "public") continue;  // the same as "all"
      scores[subset] = s->scores.at(subset);
    }
    json["scores"] = scores;
  }
  // Per-photo numbers: to the submission's own participant only, and of the public photos only
  // until the reveal (docs/benchmark.md, "Who sees what").
  if (viewer && viewer->id == s->participant_id) {
    std::set<std::string> visible;
    for (const auto& image : dataset->info.at("test_images")) visible.insert(image.at("stem"));
    if (split && !revealed) {
      visible.clear();
      for (const auto& stem : settings.at("public_stems")) visible.insert(stem);
    }
    nlohmann::json images = nlohmann::json::array();
    for (auto& row : PerImageRows(SubmissionRunFolder(store.root(), id) / "per_image.csv")) {
      if (row.contains("name") && row["name"].is_string() && visible.count(row["name"])) {
        images.push_back(std::move(row));
      }
    }
    json["images"] = images;
  }
  return json;
}

nlohmann::json ParticipantSubmissionsJson(Store& store, const ParticipantRecord& participant,
                                          const nlohmann::json& quota) {
  nlohmann::json list = nlohmann::json::array();
  for (const SubmissionRecord& s : store.ParticipantSubmissions(participant.id)) {
    list.push_back({{"id", s.id},
                    {"dataset", s.dataset},
                    {"method", s.method},
                    {"status", StatusName(s.status)},
                    {"created", s.created},
                    {"url", "/api/submissions/" + s.id}});
  }
  return {{"participant", participant.name}, {"quota", quota}, {"submissions", list}};
}

std::string JsonText(const nlohmann::json& json, int indent) {
  return json.dump(indent, ' ', false, nlohmann::json::error_handler_t::replace);
}

}  // namespace rephoto::service
