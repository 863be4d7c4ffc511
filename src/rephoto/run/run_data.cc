#include "rephoto/run/run_data.h"

#include <fmt/format.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/run/records.h"
#include "rephoto/run/run_table.h"

namespace rephoto::run {
namespace fs = std::filesystem;
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// An integer cell narrowed to int; Error naming the file, line and column when it does not fit.
int NarrowInteger(const RunTable& table, size_t row, int column) {
  const int64_t value = table.Integer(row, column);
  REPHOTO_CHECK(value >= -2000000000 && value <= 2000000000,
                "{}: line {}: column \"{}\": {} is out of range", table.file.string(), row + 2,
                table.columns[column], value);
  return static_cast<int>(value);
}

nlohmann::ordered_json ReadJson(const fs::path& path) {
  const std::string text = ReadFileToString(path);
  try {
    return nlohmann::ordered_json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    ThrowError("{}: not valid JSON: {}", path.string(), e.what());
  }
}

std::string JsonText(const nlohmann::ordered_json& j) {
  return j.is_string() ? j.get<std::string>() : j.dump();
}

}  // namespace

int RunData::MetricIndex(const std::string& metric) const {
  for (size_t i = 0; i < metrics.size(); ++i) {
    if (metrics[i] == metric) return static_cast<int>(i);
  }
  return -1;
}

std::vector<double> RunData::ImageValues(int metric) const {
  std::vector<double> values;
  for (const ImageRow& image : images) {
    if (image.status != "ok") continue;
    values.push_back(metric < 0 ? image.completeness : image.metrics[metric]);
  }
  return values;
}

std::vector<double> RunData::FoldValues(int metric) const {
  std::vector<double> values;
  for (const FoldRow& fold : folds) {
    if (fold.status != "ok") continue;
    values.push_back(metric < 0 ? fold.completeness : fold.metrics[metric]);
  }
  return values;
}

std::vector<double> RunData::Values(int metric) const {
  return AcrossFolds() ? FoldValues(metric) : ImageValues(metric);
}

fs::path RunData::ImageDir(const ImageRow& image) const {
  if (layout == RunLayout::kCompare || image.fold.empty()) return dir;
  int number = 0;
  const char* end = image.fold.data() + image.fold.size();
  const auto [ptr, ec] = std::from_chars(image.fold.data(), end, number);
  if (ec == std::errc() && ptr == end) return dir / "folds" / fmt::format("fold_{:02d}", number);
  return dir / "folds" / image.fold;
}

namespace {

fs::path Resolve(const std::string& written, const std::vector<fs::path>& bases) {
  if (written.empty()) return {};
  const fs::path path(written);
  std::error_code ec;
  if (path.is_absolute()) return fs::exists(path, ec) ? path : fs::path();
  for (const fs::path& base : bases) {
    if (fs::exists(base / path, ec)) return base / path;
  }
  if (fs::exists(path, ec)) return path;
  return {};
}

// Whether `path` (symbolic links and ".." resolved) lies inside `folder`.
bool Inside(const fs::path& path, const fs::path& folder) {
  std::error_code ec;
  const fs::path p = fs::weakly_canonical(fs::absolute(path), ec);
  if (ec) return false;
  const fs::path f = fs::weakly_canonical(fs::absolute(folder), ec);
  if (ec) return false;
  const auto [f_end, p_end] = std::mismatch(f.begin(), f.end(), p.begin(), p.end());
  return f_end == f.end();
}

}  // namespace

fs::path RunData::Readable(const fs::path& path) const {
  if (path.empty()) return {};
  if (Inside(path, dir)) return path;
  for (const fs::path& folder : image_folders) {
    if (Inside(path, folder)) return path;
  }
  return {};
}

fs::path RunData::RenderPath(const ImageRow& image) const {
  return Readable(Resolve(image.render, {ImageDir(image), dir, dir.parent_path()}));
}

fs::path RunData::PhotoPath(const ImageRow& image) const {
  if (layout == RunLayout::kEvaluate && run.is_object() && run.contains("inputs") &&
      run["inputs"].is_object() && run["inputs"].contains("photos") &&
      run["inputs"]["photos"].is_array()) {
    for (const auto& photo : run["inputs"]["photos"]) {
      if (!photo.is_object() || photo.value("name", nlohmann::ordered_json()) != image.photo)
        continue;
      const nlohmann::ordered_json path = photo.value("path", nlohmann::ordered_json());
      std::error_code ec;
      if (path.is_string() && fs::is_regular_file(path.get<std::string>(), ec)) {
        return Readable(path.get<std::string>());
      }
    }
  }
  return Readable(Resolve(image.photo, {ImageDir(image), dir, dir.parent_path()}));
}

RunData LoadRun(const fs::path& dir) {
  RunData run;
  run.dir = dir.lexically_normal();
  if (!run.dir.has_filename() && run.dir.has_parent_path()) run.dir = run.dir.parent_path();
  std::error_code ec;
  REPHOTO_CHECK(fs::is_directory(dir, ec), "{}: not a directory", dir.string());
  const fs::path per_image_path = dir / "per_image.csv";
  REPHOTO_CHECK(fs::exists(per_image_path, ec),
                "{}: not a run directory (no per_image.csv; expected the output of `rephoto "
                "evaluate` or `rephoto compare`)",
                dir.string());
  if (fs::exists(dir / "summary.json", ec)) run.summary = ReadJson(dir / "summary.json");
  if (fs::exists(dir / "run.json", ec)) run.run = ReadJson(dir / "run.json");

  run.image_table = ReadRunTable(per_image_path);
  const RunTable& per_image = run.image_table;
  const bool has_fold = !per_image.columns.empty() && per_image.columns[0] == "fold";
  const std::string schema = run.summary.is_object() && run.summary.contains("schema")
                                 ? JsonText(run.summary["schema"])
                                 : "";
  run.layout = has_fold || schema.rfind("rephoto.evaluate", 0) == 0 ? RunLayout::kEvaluate
                                                                    : RunLayout::kCompare;

  std::vector<int> metric_columns;
  for (size_t i = 0; i < per_image.columns.size(); ++i) {
    const std::string& column = per_image.columns[i];
    if (metrics::ParseMetric(column)) {
      run.metrics.push_back(column);
      metric_columns.push_back(static_cast<int>(i));
    }
  }
  const int name = per_image.Column("name");
  const int status = per_image.Column("status");
  const int completeness = per_image.Column("completeness");
  const int fold = has_fold ? 0 : -1;
  const int photo = per_image.Find("photo");
  const int render = per_image.Find("render");
  const int width = per_image.Find("width");
  const int height = per_image.Find("height");
  for (size_t r = 0; r < per_image.rows.size(); ++r) {
    ImageRow row;
    if (fold >= 0) row.fold = per_image.Text(r, fold);
    row.name = per_image.Text(r, name);
    row.status = per_image.Text(r, status);
    REPHOTO_CHECK(!row.name.empty(), "{}: line {}: empty name", per_image_path.string(), r + 2);
    if (photo >= 0) row.photo = per_image.Text(r, photo);
    if (render >= 0) row.render = per_image.Text(r, render);
    if (width >= 0) row.width = NarrowInteger(per_image, r, width);
    if (height >= 0) row.height = NarrowInteger(per_image, r, height);
    row.completeness = per_image.Number(r, completeness);
    for (int column : metric_columns) row.metrics.push_back(per_image.Number(r, column));
    if (row.status != "ok") {
      run.missing.push_back(
          fmt::format("{}{}: {}", row.fold.empty() ? "" : row.fold + "/", row.name, row.status));
    }
    run.images.push_back(std::move(row));
  }

  if (run.layout == RunLayout::kEvaluate) {
    const fs::path per_fold_path = dir / "per_fold.csv";
    REPHOTO_CHECK(fs::exists(per_fold_path, ec),
                  "{}: evaluate run without per_fold.csv (incomplete run directory)", dir.string());
    run.fold_table = ReadRunTable(per_fold_path);
    const RunTable& per_fold = run.fold_table;
    const int f_fold = per_fold.Column("fold");
    const int f_status = per_fold.Column("status");
    const int f_completeness = per_fold.Column("completeness");
    const int f_test = per_fold.Find("test_images");
    const int f_evaluated = per_fold.Find("evaluated_images");
    const int f_seconds = per_fold.Find("seconds");
    const int f_message = per_fold.Find("message");
    std::vector<int> f_metrics;
    for (const std::string& metric : run.metrics) f_metrics.push_back(per_fold.Find(metric));
    for (size_t r = 0; r < per_fold.rows.size(); ++r) {
      FoldRow row;
      row.fold = per_fold.Text(r, f_fold);
      row.status = per_fold.Text(r, f_status);
      if (f_test >= 0) row.test_images = NarrowInteger(per_fold, r, f_test);
      if (f_evaluated >= 0) row.evaluated_images = NarrowInteger(per_fold, r, f_evaluated);
      if (f_seconds >= 0) row.seconds = per_fold.Number(r, f_seconds);
      if (f_message >= 0) row.message = per_fold.Text(r, f_message);
      row.completeness = per_fold.Number(r, f_completeness);
      for (int column : f_metrics) {
        row.metrics.push_back(column >= 0 ? per_fold.Number(r, column) : kNaN);
      }
      run.folds.push_back(std::move(row));
    }
    // Seconds live in run.json only (tables are reproducible); older runs had the column.
    if (f_seconds < 0 && run.run.is_object() && run.run.contains("folds") &&
        run.run["folds"].is_array()) {
      for (const auto& entry : run.run["folds"]) {
        if (!entry.is_object() || !entry.contains("fold") || !entry.contains("seconds") ||
            !entry["seconds"].is_number()) {
          continue;
        }
        for (FoldRow& row : run.folds) {
          if (row.fold == JsonText(entry["fold"])) row.seconds = entry["seconds"].get<double>();
        }
      }
    }
  }

  // Failed folds: summary.json's list (with messages), else the per_fold.csv status.
  if (run.summary.is_object() && run.summary.contains("failed_folds") &&
      run.summary["failed_folds"].is_array()) {
    for (const auto& f : run.summary["failed_folds"]) {
      FailedFold failed;
      if (f.is_object()) {
        if (f.contains("fold")) failed.fold = JsonText(f["fold"]);
        if (f.contains("message")) failed.message = JsonText(f["message"]);
      } else {
        failed.fold = JsonText(f);
      }
      run.failed_folds.push_back(std::move(failed));
    }
  } else {
    for (const FoldRow& f : run.folds) {
      if (f.status != "ok") {
        run.failed_folds.push_back({f.fold, f.message.empty() ? f.status : f.message});
      }
    }
  }
  // Missing entries of summary.json not already listed by a per_image.csv row.
  if (run.summary.is_object() && run.summary.contains("missing") &&
      run.summary["missing"].is_array() && run.missing.empty()) {
    for (const auto& m : run.summary["missing"]) {
      if (m.is_object() && m.contains("name")) {
        run.missing.push_back(
            fmt::format("{}: missing {}", JsonText(m["name"]),
                        m.contains("missing") ? JsonText(m["missing"]) : std::string("?")));
      } else {
        run.missing.push_back(JsonText(m));
      }
    }
  }
  return run;
}

}  // namespace rephoto::run
