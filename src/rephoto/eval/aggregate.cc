#include "rephoto/eval/aggregate.h"

#include <algorithm>
#include <limits>

#include "rephoto/core/file.h"
#include "rephoto/eval/compat_numbers.h"
#include "rephoto/eval/run_records.h"
#include "rephoto/io/csv.h"

namespace rephoto::eval {
namespace fs = std::filesystem;
using run::JsonNumber;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// What the fold rows and the summary are made of.
struct Tables {
  io::CsvWriter per_image, per_fold;
  size_t per_image_columns = 0;
  std::vector<compare::ImageResult> all_images;
  std::vector<double> fold_completeness;
  std::vector<std::vector<double>> fold_metric;  // per metric, per fold
  Json failed = Json::array();
};

Tables StartTables(const EvaluateOptions& o) {
  Tables t;
  std::vector<std::string> header = {"fold"};
  for (std::string& column : compare::PerImageCsvHeader(o.metrics)) header.push_back(column);
  for (std::string& column : CompatColumns(o)) header.push_back(column);
  t.per_image.AddRow(header);
  t.per_image_columns = header.size();
  std::vector<std::string> fold_header = {"fold", "status", "test_images", "evaluated_images",
                                          "completeness"};
  for (metrics::Metric m : o.metrics) fold_header.emplace_back(metrics::MetricName(m));
  fold_header.push_back("message");
  t.per_fold.AddRow(fold_header);
  t.fold_metric.resize(o.metrics.size());
  return t;
}

// The fold's rows of per_image.csv and per_fold.csv, and its FoldResult.
FoldResult AggregateFold(const RunContext& ctx, const FoldPlan& plan, const FoldOutcome& fold,
                         Tables& t) {
  const size_t metric_count = ctx.options.metrics.size();
  FoldResult fr;
  fr.index = plan.index;
  fr.name = plan.name;
  fr.test_images = plan.tests.size();
  fr.external_seconds = fold.command.external_seconds;
  std::vector<std::pair<std::string, std::vector<std::string>>> rows;
  std::vector<double> completeness;
  std::vector<std::vector<double>> means(metric_count);
  size_t failed_views = 0;
  double seconds = fold.command.seconds + fold.model.colorize_seconds;
  for (size_t i = 0; i < plan.tests.size(); ++i) {
    const TestView& test = plan.tests[i];
    const ViewOutcome* outcome = i < fold.views.size() ? &fold.views[i] : nullptr;
    std::vector<std::string> row = {plan.name};
    if (fold.ok && outcome && outcome->ok) {
      for (std::string& field : compare::PerImageCsvRow(outcome->image)) row.push_back(field);
      // The photo by its scene name (relative to the scene's image root), not by a path into
      // this run's cache: two runs of the same inputs give byte-identical tables.
      row[3] = test.name;
      for (const compare::MetricValue& value : outcome->compat) {
        row.push_back(io::CsvNumber(value.mean));
      }
      completeness.push_back(outcome->image.completeness.value);
      for (size_t k = 0; k < metric_count; ++k) means[k].push_back(outcome->image.metrics[k].mean);
      t.all_images.push_back(outcome->image);
      seconds += outcome->render_seconds + outcome->compare_seconds;
      ++fr.evaluated_images;
    } else {
      row.insert(row.end(), {test.stem, "failed", test.name, ""});
      ++failed_views;
    }
    row.resize(t.per_image_columns);
    rows.emplace_back(test.stem, std::move(row));
  }
  std::sort(rows.begin(), rows.end());
  for (const auto& row : rows) t.per_image.AddRow(row.second);

  fr.ok = fold.ok && failed_views == 0;
  fr.message = fold.message;
  if (fold.ok && failed_views > 0) {
    for (const ViewOutcome& v : fold.views) {
      if (!v.ok && !v.message.empty()) {
        fr.message = fmt::format("{} of {} views failed, first: {}", failed_views,
                                 plan.tests.size(), v.message);
        break;
      }
    }
    if (fr.message.empty()) fr.message = fmt::format("{} views not evaluated", failed_views);
  }
  fr.seconds = seconds;
  fr.completeness = completeness.empty() ? kNaN : Summarize(completeness).mean;
  for (size_t k = 0; k < metric_count; ++k) {
    const Summary summary = Summarize(means[k]);
    fr.metric_means.push_back(summary.count ? summary.mean : kNaN);
    t.fold_metric[k].push_back(fr.metric_means.back());
  }
  t.fold_completeness.push_back(fr.completeness);
  std::vector<std::string> fold_row = {
      plan.name, fr.ok ? "ok" : "failed", std::to_string(fr.test_images),
      std::to_string(fr.evaluated_images), io::CsvNumber(fr.completeness)};
  for (double v : fr.metric_means) fold_row.push_back(io::CsvNumber(v));
  fold_row.push_back(fr.message);
  t.per_fold.AddRow(fold_row);
  if (!fr.ok) t.failed.push_back({{"fold", plan.name}, {"message", fr.message}});
  return fr;
}

Json SummaryJson(const RunContext& s, size_t folds, const Tables& t, const EvaluateResult& result) {
  // Pooled completeness: all valid windows together.
  size_t valid_photo = 0, valid_both = 0;
  for (const compare::ImageResult& image : t.all_images) {
    valid_photo += image.completeness.valid_photo;
    valid_both += image.completeness.valid_both;
  }
  Json summary;
  summary["schema"] = kSchema;
  summary["tool_version"] = compare::ToolVersion();
  summary["scene"] = fs::absolute(s.options.scene).lexically_normal().string();
  summary["scheme"] = s.split.scheme.ToString();
  // A fixed --model saw every photo, the test photos among them, whatever the split; image-based
  // rendering without a model uses only each fold's training photos.
  summary["cross_validated"] =
      s.split.cross_validated && (s.source != ModelSource::kModel || s.options.model.empty());
  summary["source"] = s.source == ModelSource::kModel         ? "model"
                      : s.source == ModelSource::kReconstruct ? "reconstruct"
                                                              : "render";
  summary["folds"] = folds;
  summary["images"] = result.images;
  summary["evaluated_images"] = result.evaluated_images;
  summary["failed_folds"] = t.failed;
  Json missing = Json::array();
  for (const std::string& name : s.missing_photos) {
    missing.push_back({{"name", name},
                       {"missing", "photo"},
                       {"path", s.scene.views[s.view_index.at(name)].image_path.string()}});
  }
  summary["missing"] = missing;
  summary["completeness"] = {
      {"across_folds", run::SummaryJson(result.completeness_across_folds, "count")},
      {"over_images", run::SummaryJson(result.completeness_over_images, "count")},
      {"pooled", valid_photo ? Json(static_cast<double>(valid_both) / valid_photo) : Json()}};
  Json metrics_json = Json::object();
  for (const MetricAggregate& a : result.metrics) {
    const auto [low, high] = compare::ErrorColourRange(a.metric);
    metrics_json[std::string(metrics::MetricName(a.metric))] = {
        {"across_folds", run::SummaryJson(a.across_folds, "count")},
        {"over_images", run::SummaryJson(a.over_images, "count")},
        {"pooled", JsonNumber(a.pooled)},
        {"higher_is_better", metrics::HigherIsBetter(a.metric)},
        {"error_png_range", {low, high}}};
  }
  summary["metrics"] = metrics_json;
  summary["files"] = {{"per_image", "per_image.csv"},
                      {"per_fold", "per_fold.csv"},
                      {"run", "run.json"},
                      {"manifest", "manifest.json"}};
  return summary;
}

}  // namespace

void Aggregate(const RunContext& s, const std::vector<FoldPlan>& plans,
               const std::vector<FoldOutcome>& folds, Tally& tally, EvaluateResult* result) {
  const auto start = Clock::now();
  Tables t = StartTables(s.options);
  for (size_t f = 0; f < plans.size(); ++f) {
    const FoldOutcome& fold = folds[f];
    FoldResult fr = AggregateFold(s, plans[f], fold, t);
    result->images += fr.test_images;
    result->evaluated_images += fr.evaluated_images;
    const bool all_views = fr.evaluated_images == fr.test_images;
    WriteFoldJson(s, plans[f], fold, fold.ok ? (all_views ? "ok" : "incomplete") : "failed");
    result->folds.push_back(std::move(fr));
  }
  std::vector<double> image_completeness;
  for (const compare::ImageResult& image : t.all_images) {
    image_completeness.push_back(image.completeness.value);
  }
  result->completeness_across_folds = Summarize(t.fold_completeness);
  result->completeness_over_images = Summarize(image_completeness);
  const std::vector<compare::MetricSummary> pooled =
      compare::SummarizeMetrics(s.options.metrics, t.all_images);
  for (size_t k = 0; k < s.options.metrics.size(); ++k) {
    MetricAggregate a;
    a.metric = s.options.metrics[k];
    a.across_folds = Summarize(t.fold_metric[k]);
    a.over_images = pooled[k].over_images;
    a.pooled = pooled[k].pooled;
    result->metrics.push_back(a);
  }
  WriteTextFileAtomically(s.run / "per_image.csv", t.per_image.text());
  WriteTextFileAtomically(s.run / "per_fold.csv", t.per_fold.text());
  Json summary = SummaryJson(s, plans.size(), t, *result);
  const Json compat = WriteCompatNumbers(s, plans, folds, result);
  if (!compat.is_null()) {
    summary["compat"] = compat;
    for (const auto& [key, file] : compat.at("files").items()) summary["files"][key] = file;
  }
  run::WriteJsonRecord(s.run / "summary.json", summary);
  tally.AddSeconds(&EvaluateTimings::aggregate, Seconds(start));
}

}  // namespace rephoto::eval
