#include "rephoto/sweep/sweep.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <limits>
#include <nlohmann/json.hpp>

#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/eval/command.h"
#include "rephoto/eval/settings.h"
#include "rephoto/report/report.h"
#include "rephoto/run/run_folder.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/split/split.h"

namespace rephoto::sweep {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// The smallest training set over the folds the base experiment will use (photos missing on
// disk are left out, as evaluate does).
int SmallestTrainingSet(const eval::EvaluateOptions& base) {
  scene::ReadSceneOptions read;
  if (!base.format.empty()) read.format = scene::ParseSceneFormat(base.format);
  if (!base.image_root.empty()) read.image_root = base.image_root;
  const scene::Scene scene = scene::ReadScene(base.scene, read);
  std::vector<std::string> names;
  for (const auto& view : scene.views) {
    if (fs::exists(view.image_path)) names.push_back(view.name);
  }
  const split::Split split =
      split::MakeSplit(names, split::ParseScheme(eval::ResolvedScheme(base, names.size())));
  size_t smallest = std::numeric_limits<size_t>::max();
  for (const auto& fold : split.folds) smallest = std::min(smallest, fold.train.size());
  REPHOTO_CHECK(!split.folds.empty(), "{}: the split has no folds", base.scene.string());
  return static_cast<int>(smallest);
}

void ApplySetting(const SweepSetting& setting, eval::EvaluateOptions* options) {
  for (const auto& [name, value] : setting.values) {
    if (name == "train_count") {
      options->train_count = static_cast<int>(value);
    } else if (name == "train_short_side") {
      options->train_short_side = static_cast<int>(value);
    } else if (name == "texture_noise") {
      options->degrade.texture_noise = static_cast<float>(value);
    } else if (name == "geometry_noise") {
      options->degrade.geometry_noise = static_cast<float>(value);
    } else if (name == "simplify") {
      options->degrade.simplify = static_cast<float>(value);
    } else if (name == "seed") {
      options->degrade.seed = static_cast<uint64_t>(value);
    }
  }
}

std::string SettingLabel(const SweepSetting& setting) {
  std::string label;
  for (const auto& [name, value] : setting.values) {
    if (!label.empty()) label += ", ";
    label += name + " " + FormatValue(value);
  }
  return label.empty() ? "base" : label;
}

}  // namespace

SweepOptions LoadSweepConfig(const fs::path& file) {
  return LoadSweepConfigText(ReadFileToString(file), file);
}

SweepOptions LoadSweepConfigText(std::string_view text, const fs::path& file) {
  SweepOptions options;
  nlohmann::json tables;
  eval::LoadConfigText(text, file, &options.base, {"sweep"}, &tables);
  REPHOTO_CHECK(tables.contains("sweep") && tables["sweep"].is_object(),
                "{}: no [sweep] table (the settings to vary)", file.string());
  const fs::path base_dir = fs::absolute(file).parent_path();
  for (const auto& [key, value] : tables["sweep"].items()) {
    const std::string source = fmt::format("{}: [sweep] {}", file.string(), key);
    if (key == "x") {
      REPHOTO_CHECK(value.is_string(), "{}: expected a parameter name", source);
      options.x_axis = value.get<std::string>();
    } else if (key == "out") {
      REPHOTO_CHECK(value.is_string(), "{}: expected a folder", source);
      options.out = base_dir / value.get<std::string>();
    } else if (key == "min_train_count") {
      REPHOTO_CHECK(value.is_number_integer() && value.get<int64_t>() >= 1,
                    "{}: expected a whole number >= 1", source);
      options.min_train_count = value.get<int>();
    } else if (key == "report") {
      REPHOTO_CHECK(value.is_boolean(), "{}: expected true or false", source);
      options.report = value.get<bool>();
    } else {
      REPHOTO_CHECK(IsSweepParameter(key),
                    "{}: unknown key (parameters: {}; also x, out, "
                    "min_train_count, report)",
                    source, SweepParameterList());
      SweepAxis axis{.parameter = key, .values = {}};
      if (key == "train_count" && value.is_string()) {
        REPHOTO_CHECK(value.get<std::string>() == "halve",
                      "{}: expected \"halve\" or a list of sizes", source);
        options.halve_train_count = true;
      } else {
        REPHOTO_CHECK(value.is_array(), "{}: expected a list of numbers", source);
        for (const auto& item : value) {
          REPHOTO_CHECK(item.is_number(), "{}: expected a list of numbers", source);
          axis.values.push_back(item.get<double>());
        }
      }
      options.axes.push_back(std::move(axis));
    }
  }
  if (options.out.empty()) options.out = base_dir / (file.stem().string() + ".sweep");
  // Config tables have no order: the axes are taken by name, with the x axis last so that it
  // varies fastest (each series runs through its x values).
  std::stable_sort(options.axes.begin(), options.axes.end(),
                   [&](const SweepAxis& a, const SweepAxis& b) {
                     const bool ax = a.parameter == options.x_axis;
                     const bool bx = b.parameter == options.x_axis;
                     if (ax != bx) return bx;
                     return a.parameter < b.parameter;
                   });
  return options;
}

SweepResult RunSweep(const SweepOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  REPHOTO_CHECK(!options.out.empty(), "sweep: no output folder");
  SweepResult result;
  result.axes = options.axes;
  for (auto& axis : result.axes) {
    if (axis.parameter == "train_count" && options.halve_train_count && axis.values.empty()) {
      axis.values = HalvingSeries(SmallestTrainingSet(options.base), options.min_train_count);
      LogInfo(fmt::format("sweep: |T| halved from the smallest fold's training set: {}",
                          fmt::join(axis.values, ", ")));
    }
  }
  CheckAxes(result.axes, "sweep");
  std::string x_axis = options.x_axis;
  if (x_axis.empty() && !result.axes.empty()) x_axis = result.axes.back().parameter;
  REPHOTO_CHECK(
      x_axis.empty() || std::any_of(result.axes.begin(), result.axes.end(),
                                    [&](const SweepAxis& a) { return a.parameter == x_axis; }),
      "sweep: the x axis '{}' is not a swept parameter", x_axis);
  const bool defects = std::any_of(result.axes.begin(), result.axes.end(), [](const auto& a) {
    return a.parameter == "texture_noise" || a.parameter == "geometry_noise" ||
           a.parameter == "simplify" || a.parameter == "seed";
  });
  REPHOTO_CHECK(!defects || options.base.source() != eval::ModelSource::kRender,
                "sweep: model defects need a model rendered by rephoto, not an external renderer");

  const std::vector<SweepSetting> settings = ExpandGrid(result.axes);
  // One writer; only a folder that holds a sweep (or nothing). Each setting's evaluate run
  // locks its own folder below it.
  const run::RunFolder run_folder =
      run::OpenRunFolder(options.out, "sweep", [](const fs::path& dir) {
        std::error_code ec;
        return fs::exists(dir / "sweep.json", ec) || fs::is_directory(dir / "settings", ec);
      });
  fs::create_directories(options.out / "settings");
  std::vector<fs::path> run_dirs;
  for (size_t s = 0; s < settings.size(); ++s) {
    SettingOutcome outcome{.setting = settings[s],
                           .run_dir = options.out / "settings" / settings[s].name};
    LogInfo(
        fmt::format("sweep: setting {}/{}: {}", s + 1, settings.size(), SettingLabel(settings[s])));
    eval::EvaluateOptions evaluate = options.base;
    evaluate.out = outcome.run_dir;
    // One cache of hashes and downscaled photos for all settings (keyed by content and size).
    if (evaluate.cache_dir.empty()) evaluate.cache_dir = options.out / "cache";
    ApplySetting(settings[s], &evaluate);
    try {
      outcome.result = eval::RunEvaluate(evaluate);
      if (outcome.result.exit_code != ExitCode::kOk) result.exit_code = ExitCode::kIncomplete;
      result.external_seconds += outcome.result.timings.external;
      result.rephoto_seconds += outcome.result.timings.rephoto();
      result.external_cpu_seconds += outcome.result.timings.external_cpu;
      result.rephoto_cpu_seconds += outcome.result.timings.rephoto_cpu;
    } catch (const eval::UsageError&) {
      throw;  // the same bad setting would fail every setting
    } catch (const Error& e) {
      if (std::string_view(e.what()).find("interrupted") != std::string_view::npos) throw;
      outcome.ok = false;
      outcome.message = e.what();
      result.exit_code = ExitCode::kIncomplete;
      LogWarning(fmt::format("sweep: setting {} failed: {}", settings[s].name, e.what()));
    }
    run_dirs.push_back(outcome.run_dir);
    result.settings.push_back(std::move(outcome));
  }

  result.table = ReadSweepTable(settings, run_dirs);
  WriteTextFileAtomically(options.out / "sweep.csv", SweepSummaryCsv(result.table, result.axes));
  WriteTextFileAtomically(options.out / "sweep_per_fold.csv",
                          SweepPerFoldCsv(result.table, result.axes));

  if (options.report) {
    std::vector<report::CollectionEntry> entries;
    for (const auto& outcome : result.settings) {
      if (!fs::exists(outcome.run_dir / "per_fold.csv")) continue;
      report::CollectionEntry entry;
      entry.label = SettingLabel(outcome.setting);
      entry.run_dir = outcome.run_dir;
      if (!x_axis.empty()) {
        entry.setting = outcome.setting.Value(x_axis);
        for (const auto& [name, value] : outcome.setting.values) {
          if (name == x_axis) continue;
          if (!entry.series.empty()) entry.series += ", ";
          entry.series += name + " " + FormatValue(value);
        }
      }
      entry.description = outcome.ok ? "" : outcome.message;
      entries.push_back(std::move(entry));
    }
    if (!entries.empty()) {
      report::CollectionOptions report_options;
      report_options.title = "rephoto sweep: " + options.out.filename().string();
      report_options.setting_name = x_axis;
      report_options.rank = false;
      report::WriteCollectionReport(entries, options.out / "report.html", report_options);
    }
  }

  result.total_seconds = Seconds(start);
  Json json;
  json["schema"] = "rephoto.sweep/1";
  json["x_axis"] = x_axis;
  Json axes = Json::array();
  for (const auto& axis : result.axes) {
    axes.push_back({{"parameter", axis.parameter}, {"values", axis.values}});
  }
  json["axes"] = axes;
  Json list = Json::array();
  for (const auto& outcome : result.settings) {
    Json entry;
    entry["name"] = outcome.setting.name;
    for (const auto& [name, value] : outcome.setting.values) entry["values"][name] = value;
    entry["run_dir"] = fs::relative(outcome.run_dir, options.out).string();
    entry["status"] = !outcome.ok                                 ? "failed"
                      : outcome.result.exit_code == ExitCode::kOk ? "ok"
                                                                  : "incomplete";
    if (!outcome.ok) entry["message"] = outcome.message;
    entry["seconds"] = {{"total", outcome.result.timings.total},
                        {"external", outcome.result.timings.external},
                        {"rephoto", outcome.result.timings.rephoto()},
                        {"external_cpu", outcome.result.timings.external_cpu},
                        {"rephoto_cpu", outcome.result.timings.rephoto_cpu}};
    list.push_back(entry);
  }
  json["settings"] = list;
  json["seconds"] = {{"total", result.total_seconds},
                     {"external", result.external_seconds},
                     {"rephoto", result.rephoto_seconds},
                     {"rephoto_share", result.rephoto_share()}};
  json["cpu_seconds"] = {{"external", result.external_cpu_seconds},
                         {"rephoto", result.rephoto_cpu_seconds},
                         {"rephoto_share", result.rephoto_cpu_share()}};
  WriteTextFileAtomically(options.out / "sweep.json", json.dump(2) + "\n");
  return result;
}

}  // namespace rephoto::sweep
