#include "rephoto/eval/compat_numbers.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <string_view>
#include <utility>

#include "rephoto/core/file.h"
#include "rephoto/run/records.h"

namespace rephoto::eval {
namespace fs = std::filesystem;
using run::JsonNumber;

namespace {

// The files each preset writes (removed when the run has no preset).
const std::vector<std::string>& ReferenceFiles() {
  static const std::vector<std::string> files = {"results.json", "per_view.json", "metrics.txt",
                                                 "output.json"};
  return files;
}

// The key the references give a metric: metrics.py "SSIM"/"PSNR"/"LPIPS", ns-eval "psnr"...
std::string UpperName(metrics::Metric metric) {
  std::string name(metrics::MetricName(metric));
  for (char& c : name) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return name;
}

bool AllDigits(std::string_view text) {
  return !text.empty() && std::all_of(text.begin(), text.end(), [](char c) {
    return std::isdigit(static_cast<unsigned char>(c)) != 0;
  });
}

// Sample standard deviation (n - 1), NaN with fewer than two values.
double SampleStd(const std::vector<double>& values) {
  if (values.size() < 2) return std::numeric_limits<double>::quiet_NaN();
  double mean = 0;
  for (double v : values) mean += v;
  mean /= static_cast<double>(values.size());
  double sum = 0;
  for (double v : values) sum += (v - mean) * (v - mean);
  return std::sqrt(sum / static_cast<double>(values.size() - 1));
}

// One evaluated view: its rendering's file name (per_view.json's key) and values.
struct CompatView {
  std::string stem;
  std::string file;
  const std::vector<compare::MetricValue>* values = nullptr;
};

// The order metrics.py prints and stores its metrics in: SSIM, PSNR, LPIPS (then any other).
std::vector<size_t> GraphdecoOrder(const std::vector<metrics::Metric>& list) {
  std::vector<size_t> order(list.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = k;
  const auto rank = [&](size_t k) {
    const std::string name(metrics::MetricName(list[k]));
    return name == "ssim" ? 0 : name == "psnr" ? 1 : name == "lpips" ? 2 : 3;
  };
  std::stable_sort(order.begin(), order.end(),
                   [&](size_t a, size_t b) { return rank(a) < rank(b); });
  return order;
}

std::string SceneFolderName(const EvaluateOptions& o) {
  const fs::path scene = fs::absolute(o.scene).lexically_normal();
  std::error_code ec;
  const fs::path folder = fs::is_directory(scene, ec) ? scene : scene.parent_path();
  std::string name = folder.filename().string();
  // "scene/sparse" or "scene/sparse/0": the scene is the folder above COLMAP's.
  fs::path up = folder;
  while ((name == "sparse" || AllDigits(name)) && up.has_parent_path() && up.parent_path() != up) {
    up = up.parent_path();
    name = up.filename().string();
  }
  return name;
}

}  // namespace

compare::CompareOptions CompatCompareSettings(const EvaluateOptions& o) {
  compare::CompareOptions c;
  c.compat = o.compat;
  c.compat_background = o.background;
  c.metrics = CompatMetrics(o);
  c.lpips_weights = o.lpips_weights;
  c.lpips_net = o.lpips_net;
  c.metric_options = o.metric_options;  // completeness window only; compat ignores the rest
  c.write_error_images = false;
  c.prefetch = false;
  return c;
}

std::vector<compare::MetricValue> CompareViewCompat(const EvaluateOptions& options,
                                                    const std::string& stem,
                                                    const fs::path& photo_path,
                                                    const fs::path& render_path, const Image& photo,
                                                    const Image& render,
                                                    compare::CompareWorkspace* workspace) {
  const compare::CompareOptions settings = CompatCompareSettings(options);
  compare::ImageResult result =
      compare::ComparePhotoAndRender(settings, stem, photo_path, render_path, photo, render,
                                     nullptr, nullptr, fs::path(), workspace);
  return std::move(result.metrics);
}

std::vector<std::string> CompatColumns(const EvaluateOptions& o) {
  std::vector<std::string> columns;
  if (!o.compat) return columns;
  for (metrics::Metric m : CompatMetrics(o)) {
    columns.push_back(
        fmt::format("{}_{}", metrics::CompatPresetName(*o.compat), metrics::MetricName(m)));
  }
  return columns;
}

std::string CompatMethodName(const EvaluateOptions& o) {
  if (o.source() == ModelSource::kModel && !o.model.empty()) {
    const std::string folder = o.model.parent_path().filename().string();
    const std::string prefix = "iteration_";
    if (folder.rfind(prefix, 0) == 0 && AllDigits(std::string_view(folder).substr(prefix.size()))) {
      return "ours_" + folder.substr(prefix.size());
    }
  }
  return "rephoto";
}

nlohmann::ordered_json WriteCompatNumbers(const RunContext& s, const std::vector<FoldPlan>& plans,
                                          const std::vector<FoldOutcome>& folds,
                                          EvaluateResult* result) {
  const EvaluateOptions& o = s.options;
  result->compat.clear();
  result->compat_text.clear();
  if (!o.compat) {
    std::error_code ec;
    for (const std::string& file : ReferenceFiles()) fs::remove(s.run / file, ec);
    return Json();
  }
  const metrics::CompatPreset preset = *o.compat;
  const std::vector<metrics::Metric> list = CompatMetrics(o);

  // The evaluated views, by stem (name order, as the tables).
  std::vector<CompatView> views;
  for (size_t f = 0; f < plans.size() && f < folds.size(); ++f) {
    if (!folds[f].ok) continue;
    for (const ViewOutcome& view : folds[f].views) {
      if (!view.ok || view.compat.size() != list.size()) continue;
      const std::string extension = fs::path(view.image.render).extension().string();
      views.push_back(
          {view.stem, view.stem + (extension.empty() ? ".png" : extension), &view.compat});
    }
  }
  std::sort(views.begin(), views.end(),
            [](const CompatView& a, const CompatView& b) { return a.stem < b.stem; });

  Json metrics_json = Json::object();
  for (size_t k = 0; k < list.size(); ++k) {
    std::vector<double> values;
    for (const CompatView& view : views) values.push_back((*view.values)[k].mean);
    CompatAggregate a;
    a.metric = list[k];
    a.over_images = Summarize(values);
    a.std = SampleStd(values);
    // A PSNR of +inf (an identical image) makes the mean +inf, as in the references.
    if (std::any_of(values.begin(), values.end(), [](double v) { return std::isinf(v); })) {
      a.over_images.mean = std::numeric_limits<double>::infinity();
    }
    metrics_json[std::string(metrics::MetricName(a.metric))] = {
        {"mean", JsonNumber(a.over_images.mean)},
        {"std", JsonNumber(a.std)},
        {"over_images", run::SummaryJson(a.over_images, "count")}};
    result->compat.push_back(a);
  }

  const std::string method = CompatMethodName(o);
  Json files = Json::object();
  if (preset == metrics::CompatPreset::k3dgs) {
    const std::vector<size_t> order = GraphdecoOrder(list);
    Json means = Json::object(), per_view = Json::object();
    std::string text = fmt::format("Scene: {}\nMethod: {}\n", s.run.string(), method);
    for (size_t k : order) {
      const std::string key = UpperName(list[k]);
      means[key] = JsonNumber(result->compat[k].over_images.mean);
      Json by_view = Json::object();
      for (const CompatView& view : views) by_view[view.file] = JsonNumber((*view.values)[k].mean);
      per_view[key] = std::move(by_view);
      text += fmt::format("  {:<5}: {:>12.7f}\n", key, result->compat[k].over_images.mean);
    }
    text += "\n";
    WriteTextFileAtomically(s.run / "results.json", Json({{method, means}}).dump(1) + "\n");
    WriteTextFileAtomically(s.run / "per_view.json", Json({{method, per_view}}).dump(1) + "\n");
    WriteTextFileAtomically(s.run / "metrics.txt", text);
    std::error_code ec;
    fs::remove(s.run / "output.json", ec);
    files = {
        {"results", "results.json"}, {"per_view", "per_view.json"}, {"printed", "metrics.txt"}};
    result->compat_text = text;
  } else {
    Json results = Json::object();
    for (size_t k = 0; k < list.size(); ++k) {
      const std::string name(metrics::MetricName(list[k]));
      results[name] = JsonNumber(result->compat[k].over_images.mean);
      results[name + "_std"] = JsonNumber(result->compat[k].std);
    }
    std::string checkpoint;
    if (o.source() == ModelSource::kRender) {
      checkpoint = o.render;
    } else if (!o.model.empty()) {
      checkpoint = o.source() == ModelSource::kModel
                       ? fs::absolute(o.model).lexically_normal().string()
                       : o.model.string();
    }
    Json output;
    output["experiment_name"] = SceneFolderName(o);
    output["method_name"] = method;
    output["checkpoint"] = checkpoint;
    output["results"] = results;
    WriteTextFileAtomically(s.run / "output.json", output.dump(2));
    std::error_code ec;
    for (const char* stale : {"results.json", "per_view.json", "metrics.txt"}) {
      fs::remove(s.run / stale, ec);
    }
    files = {{"output", "output.json"}};
    result->compat_text = fmt::format("{}\nSaved results to: {}\n", results.dump(2),
                                      (s.run / "output.json").string());
  }
  return {{"preset", metrics::CompatPresetName(preset)},
          {"background", o.background},
          {"method", method},
          {"images", views.size()},
          {"metrics", metrics_json},
          {"files", files}};
}

}  // namespace rephoto::eval
