#include "rephoto/eval/result_text.h"

#include <fmt/format.h>

#include <cmath>

#include "rephoto/core/file.h"
#include "rephoto/run/records.h"
#include "rephoto/run/run_data.h"
#include "rephoto/run/summary_table.h"

namespace rephoto::eval {
namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;

std::string ResultText(const EvaluateResult& result, const fs::path& out) {
  std::string text = fmt::format(
      "{} folds, {} of {} test images evaluated ({} views reused, {} rendered, {} "
      "commands run)\n",
      result.folds.size(), result.evaluated_images, result.images, result.counters.views_reused,
      result.counters.views_rendered, result.counters.commands_run);
  std::vector<run::SummaryRow> rows = {
      {"completeness", result.completeness_across_folds, 0, false}};
  for (const MetricAggregate& m : result.metrics) {
    rows.push_back({std::string(metrics::MetricName(m.metric)), m.across_folds, m.pooled});
  }
  text += run::FormatSummaryTable("", "fold mean", rows);
  if (!result.compat_text.empty()) {
    // The published numbers (--compat), as the reference prints them.
    text += fmt::format("\nWhole-image numbers as papers publish them ({}):\n{}",
                        result.compat_text.rfind("Scene: ", 0) == 0
                            ? "graphdeco's metrics.py: results.json, per_view.json"
                            : "nerfstudio's ns-eval: output.json",
                        result.compat_text);
  }
  for (const FoldResult& fold : result.folds) {
    if (!fold.ok) text += fmt::format("failed: {}\n", fold.message);
  }
  for (const std::string& name : result.missing_photos) {
    text += fmt::format("missing photo: {}\n", name);
  }
  const EvaluateTimings& t = result.timings;
  const std::string cpu =
      t.external_cpu > 0 ? fmt::format("; CPU: commands {:.1f} s, rephoto {:.1f} s = {:.1f} %",
                                        t.external_cpu, t.rephoto_cpu, 100 * t.rephoto_cpu_share())
                         : "";
  // The commands of several folds run at once and beside rephoto's own work, so their summed
  // times can exceed the wall-clock total; the line says so when they do.
  const bool overlapped = t.external + t.rephoto() > t.total + 0.05;
  text += fmt::format(
      "Time {:.1f} s wall clock (external commands {:.1f} s, rephoto {:.1f} s{}{}). Results in "
      "{}\n",
      t.total, t.external, t.rephoto(), overlapped ? ", summed over work that ran at the same time" : "",
      cpu, out.string());
  return text;
}

namespace {

Summary SummaryFromJson(const Json& j) {
  Summary s;
  s.mean = run::NumberFromJson(j.value("mean", Json()));
  s.min = run::NumberFromJson(j.value("min", Json()));
  s.q1 = run::NumberFromJson(j.value("q1", Json()));
  s.median = run::NumberFromJson(j.value("median", Json()));
  s.q3 = run::NumberFromJson(j.value("q3", Json()));
  s.max = run::NumberFromJson(j.value("max", Json()));
  s.count = j.value("count", size_t{0});
  return s;
}

}  // namespace

EvaluateResult ReadEvaluateResult(const fs::path& run_dir) {
  const fs::path summary_path = run_dir / "summary.json";
  const std::optional<Json> summary = run::ReadJsonRecord(summary_path);
  REPHOTO_CHECK(summary && summary->value("schema", "") == "rephoto.evaluate/1",
                "{}: missing or not an evaluate summary", summary_path.string());
  EvaluateResult result;
  result.images = summary->value("images", size_t{0});
  result.evaluated_images = summary->value("evaluated_images", size_t{0});
  const Json& completeness = summary->at("completeness");
  result.completeness_across_folds = SummaryFromJson(completeness.at("across_folds"));
  result.completeness_over_images = SummaryFromJson(completeness.at("over_images"));
  std::vector<metrics::Metric> metric_list;
  for (const auto& [name, m] : summary->at("metrics").items()) {
    const std::optional<metrics::Metric> metric = metrics::ParseMetric(name);
    REPHOTO_CHECK(metric.has_value(), "{}: unknown metric '{}'", summary_path.string(), name);
    metric_list.push_back(*metric);
    MetricAggregate a;
    a.metric = *metric;
    a.across_folds = SummaryFromJson(m.at("across_folds"));
    a.over_images = SummaryFromJson(m.at("over_images"));
    a.pooled = run::NumberFromJson(m.value("pooled", Json()));
    result.metrics.push_back(a);
  }
  for (const Json& missing : summary->value("missing", Json::array())) {
    result.missing_photos.push_back(missing.value("name", ""));
  }
  if (summary->contains("compat") && summary->at("compat").is_object()) {
    // What the run printed of the --compat numbers (its reference files).
    const Json& compat = summary->at("compat");
    std::error_code ec;
    if (compat.value("preset", "") == "3dgs" && fs::is_regular_file(run_dir / "metrics.txt", ec)) {
      result.compat_text = ReadFileToString(run_dir / "metrics.txt");
    } else if (const std::optional<Json> output = run::ReadJsonRecord(run_dir / "output.json")) {
      result.compat_text = fmt::format("{}\nSaved results to: {}\n",
                                       output->value("results", Json::object()).dump(2),
                                       (run_dir / "output.json").string());
    }
  }
  // The folds as run/run_data.h reads per_fold.csv.
  const run::RunData run = run::LoadRun(run_dir);
  for (size_t f = 0; f < run.folds.size(); ++f) {
    const run::FoldRow& row = run.folds[f];
    FoldResult fold;
    fold.index = f;
    fold.name = row.fold;
    fold.ok = row.status == "ok";
    fold.test_images = static_cast<size_t>(row.test_images);
    fold.evaluated_images = static_cast<size_t>(row.evaluated_images);
    fold.completeness = row.completeness;
    for (metrics::Metric metric : metric_list) {
      const int k = run.MetricIndex(std::string(metrics::MetricName(metric)));
      fold.metric_means.push_back(k >= 0 ? row.metrics[k] : std::nan(""));
    }
    fold.message = row.message;
    result.folds.push_back(std::move(fold));
  }
  bool incomplete = !result.missing_photos.empty();
  for (const FoldResult& fold : result.folds) incomplete |= !fold.ok;
  result.exit_code = incomplete ? ExitCode::kIncomplete : ExitCode::kOk;
  return result;
}

}  // namespace rephoto::eval
