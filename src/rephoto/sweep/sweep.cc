#include "rephoto/sweep/sweep.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <limits>
#include <nlohmann/json.hpp>

#include "rephoto/cluster/slurm_settings.h"
#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/eval/command_template.h"
#include "rephoto/eval/result_text.h"
#include "rephoto/eval/settings.h"
#include "rephoto/eval/slurm_executor.h"
#include "rephoto/geometry/run_geometry.h"
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

// The base experiment's scene, read as evaluate reads it.
scene::Scene ReadBaseScene(const eval::EvaluateOptions& base) {
  scene::ReadSceneOptions read;
  if (!base.format.empty()) read.format = scene::ParseSceneFormat(base.format);
  if (!base.image_root.empty()) read.image_root = base.image_root;
  return scene::ReadScene(base.scene, read);
}

// The smallest training set over the folds the base experiment will use (photos missing on
// disk are left out, as evaluate does).
int SmallestTrainingSet(const eval::EvaluateOptions& base) {
  const scene::Scene scene = ReadBaseScene(base);
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
  eval::LoadConfigText(text, file, &options.base, {"sweep", "slurm"}, &tables);
  if (tables.contains("slurm")) {
    cluster::ApplySlurmTable(options.base.slurm, tables["slurm"], file.string());
  }
  REPHOTO_CHECK_USAGE(tables.contains("sweep") && tables["sweep"].is_object(),
                      "{}: no [sweep] table (the settings to vary)", file.string());
  const fs::path base_dir = fs::absolute(file).parent_path();
  for (const auto& [key, value] : tables["sweep"].items()) {
    const std::string source = fmt::format("{}: [sweep] {}", file.string(), key);
    if (key == "x") {
      REPHOTO_CHECK_USAGE(value.is_string(), "{}: expected a parameter name", source);
      options.x_axis = value.get<std::string>();
    } else if (key == "out") {
      REPHOTO_CHECK_USAGE(value.is_string(), "{}: expected a folder", source);
      options.out = base_dir / value.get<std::string>();
    } else if (key == "min_train_count") {
      REPHOTO_CHECK_USAGE(value.is_number_integer() && value.get<int64_t>() >= 1,
                          "{}: expected a whole number >= 1", source);
      options.min_train_count = value.get<int>();
    } else if (key == "report") {
      REPHOTO_CHECK_USAGE(value.is_boolean(), "{}: expected true or false", source);
      options.report = value.get<bool>();
    } else if (key == "reference") {
      REPHOTO_CHECK(value.is_string() && !value.get<std::string>().empty(),
                    "{}: expected a mesh or point cloud file", source);
      options.reference = base_dir / value.get<std::string>();
    } else if (key == "tolerances") {
      REPHOTO_CHECK(value.is_array() && !value.empty(), "{}: expected a list of numbers > 0",
                    source);
      options.geometry.tolerances.clear();
      for (const auto& item : value) {
        REPHOTO_CHECK(item.is_number() && item.get<double>() > 0,
                      "{}: expected a list of numbers > 0", source);
        options.geometry.tolerances.push_back(item.get<double>());
      }
    } else if (key == "accuracy_fraction") {
      REPHOTO_CHECK(value.is_number() && value.get<double>() > 0 && value.get<double>() <= 1,
                    "{}: expected a number in (0, 1]", source);
      options.geometry.accuracy_fraction = value.get<double>();
    } else if (key == "geometry_samples") {
      REPHOTO_CHECK(value.is_number_integer() && value.get<int64_t>() >= 1,
                    "{}: expected a whole number >= 1", source);
      options.geometry.samples = value.get<size_t>();
    } else {
      REPHOTO_CHECK_USAGE(IsSweepParameter(key),
                          "{}: unknown key (parameters: {}; also x, out, "
                          "min_train_count, report, reference, tolerances, accuracy_fraction, "
                          "geometry_samples)",
                          source, SweepParameterList());
      SweepAxis axis{.parameter = key, .values = {}};
      if (key == "train_count" && value.is_string()) {
        REPHOTO_CHECK_USAGE(value.get<std::string>() == "halve",
                            "{}: expected \"halve\" or a list of sizes", source);
        options.halve_train_count = true;
      } else {
        REPHOTO_CHECK_USAGE(value.is_array(), "{}: expected a list of numbers", source);
        for (const auto& item : value) {
          REPHOTO_CHECK_USAGE(item.is_number(), "{}: expected a list of numbers", source);
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

namespace {

// What the settings need before they run: the resolved axes, the x axis and the grid.
struct SweepPlan {
  std::vector<SweepSetting> settings;
  std::string x_axis;
};

SweepPlan PlanSweep(const SweepOptions& options, SweepResult* result) {
  REPHOTO_CHECK(!options.out.empty(), "sweep: no output folder");
  REPHOTO_CHECK(options.reference.empty() || fs::is_regular_file(options.reference),
                "{}: the sweep's geometric reference does not exist or is not a file",
                options.reference.string());
  if (!options.reference.empty()) options.geometry.Check();
  result->axes = options.axes;
  for (auto& axis : result->axes) {
    if (axis.parameter == "train_count" && options.halve_train_count && axis.values.empty()) {
      axis.values = HalvingSeries(SmallestTrainingSet(options.base), options.min_train_count);
      LogInfo(fmt::format("sweep: |T| halved from the smallest fold's training set: {}",
                          fmt::join(axis.values, ", ")));
    }
  }
  CheckAxes(result->axes, "sweep");
  SweepPlan plan;
  plan.x_axis = options.x_axis;
  if (plan.x_axis.empty() && !result->axes.empty()) plan.x_axis = result->axes.back().parameter;
  REPHOTO_CHECK_USAGE(plan.x_axis.empty() || std::any_of(result->axes.begin(), result->axes.end(),
                                                         [&](const SweepAxis& a) {
                                                           return a.parameter == plan.x_axis;
                                                         }),
                      "sweep: the x axis '{}' is not a swept parameter", plan.x_axis);
  const bool defects = std::any_of(result->axes.begin(), result->axes.end(), [](const auto& a) {
    return a.parameter == "texture_noise" || a.parameter == "geometry_noise" ||
           a.parameter == "simplify" || a.parameter == "seed";
  });
  REPHOTO_CHECK_USAGE(
      !defects || options.base.source() != eval::ModelSource::kRender,
      "sweep: model defects need a model rendered by rephoto, not an external renderer");
  plan.settings = ExpandGrid(result->axes);
  return plan;
}

// The evaluate options of one setting.
eval::EvaluateOptions SettingOptions(const SweepOptions& options, const SweepSetting& setting) {
  eval::EvaluateOptions evaluate = options.base;
  evaluate.out = options.out / "settings" / setting.name;
  // One cache of hashes and downscaled photos for all settings (keyed by content and size).
  if (evaluate.cache_dir.empty()) evaluate.cache_dir = options.out / "cache";
  ApplySetting(setting, &evaluate);
  return evaluate;
}

// Every setting's evaluate options checked before anything is written: a bad value in the
// config (a scheme, a metric) would otherwise only show when the first setting runs.
void CheckSettings(const SweepOptions& options, const SweepPlan& plan) {
  for (const SweepSetting& setting : plan.settings) {
    try {
      SettingOptions(options, setting).Check();
    } catch (const UsageError& e) {
      if (options.base.config_file.empty()) throw;
      throw UsageError(fmt::format("{}: {}", options.base.config_file.string(), e.what()));
    }
  }
}

void AddTimings(const eval::EvaluateResult& r, SweepResult* result) {
  result->external_seconds += r.timings.external;
  result->rephoto_seconds += r.timings.rephoto();
  result->external_cpu_seconds += r.timings.external_cpu;
  result->rephoto_cpu_seconds += r.timings.rephoto_cpu;
}

// Each setting's evaluation in this process, one after the other.
void RunSettings(const SweepOptions& options, const SweepPlan& plan, SweepResult* result) {
  for (size_t s = 0; s < plan.settings.size(); ++s) {
    const SweepSetting& setting = plan.settings[s];
    SettingOutcome outcome{.setting = setting, .run_dir = options.out / "settings" / setting.name};
    LogInfo(fmt::format("sweep: setting {}/{}: {}", s + 1, plan.settings.size(),
                        SettingLabel(setting)));
    eval::EvaluateOptions evaluate = SettingOptions(options, setting);
    evaluate.executor = eval::Executor::kLocal;
    try {
      outcome.result = eval::RunEvaluate(evaluate);
      if (outcome.result.exit_code != ExitCode::kOk) result->exit_code = ExitCode::kIncomplete;
      AddTimings(outcome.result, result);
    } catch (const UsageError&) {
      throw;  // the same bad setting would fail every setting
    } catch (const Interrupted&) {
      throw;
    } catch (const Error& e) {
      outcome.ok = false;
      outcome.message = e.what();
      result->exit_code = ExitCode::kIncomplete;
      LogWarning(fmt::format("sweep: setting {} failed: {}", setting.name, e.what()));
    }
    result->settings.push_back(std::move(outcome));
  }
}

// Each setting's results as its run folder holds them (the sweep's aggregation task, after the
// settings ran elsewhere).
void CollectSettings(const SweepOptions& options, const SweepPlan& plan, SweepResult* result) {
  for (const SweepSetting& setting : plan.settings) {
    SettingOutcome outcome{.setting = setting, .run_dir = options.out / "settings" / setting.name};
    try {
      outcome.result = eval::ReadEvaluateResult(outcome.run_dir);
      if (outcome.result.exit_code != ExitCode::kOk) result->exit_code = ExitCode::kIncomplete;
    } catch (const Error& e) {
      outcome.ok = false;
      outcome.message = e.what();
      result->exit_code = ExitCode::kIncomplete;
    }
    result->settings.push_back(std::move(outcome));
  }
}

// The settings as Slurm job arrays: every setting's fold, view and aggregation tasks, then one
// task that aggregates the sweep (`rephoto sweep CONFIG --out OUT --only-aggregate`).
bool RunSettingsOnSlurm(const SweepOptions& options, const SweepPlan& plan, SweepResult* result) {
  std::vector<cluster::TaskGroup> groups = {
      {"fold", {}, options.base.source() != eval::ModelSource::kModel},
      {"views", {}, false},
      {"aggregate", {}, false},
      {"sweep", {}, false}};
  size_t tasks = 0, done_before = 0;
  for (const SweepSetting& setting : plan.settings) {
    eval::EvaluatePlan evaluate_plan;
    const std::vector<cluster::TaskGroup> setting_groups = eval::PrepareEvaluateTasks(
        SettingOptions(options, setting), setting.name + "/", eval::PlanEvaluate, &evaluate_plan);
    for (size_t g = 0; g < setting_groups.size(); ++g) {
      for (const cluster::Task& task : setting_groups[g].tasks) groups[g].tasks.push_back(task);
    }
    tasks += evaluate_plan.tasks.size();
    for (const eval::EvaluateTask& task : evaluate_plan.tasks) done_before += task.done;
  }
  REPHOTO_CHECK_USAGE(!options.base.config_file.empty(),
                      "sweep: --executor slurm needs the sweep's config file");
  const fs::path program =
      options.base.program.empty() ? eval::ThisExecutable() : options.base.program;
  std::vector<std::string> argv = {
      program.string(),  "-q",
      "sweep",           fs::absolute(options.base.config_file).string(),
      "--out",           fs::absolute(options.out).string(),
      "--only-aggregate"};
  if (!options.report) argv.push_back("--no-report");
  const bool sweep_done = done_before == tasks && fs::exists(options.out / "sweep.json");
  if (!sweep_done) {
    std::string key;
    for (const cluster::TaskGroup& group : groups) {
      for (const cluster::Task& task : group.tasks) key += task.key;
    }
    groups[3].tasks.push_back({"sweep/aggregate", argv, key, std::nullopt});
  }
  cluster::SlurmOptions slurm = cluster::ResolveReconstructResources(options.base.slurm);
  slurm.interrupted = [] { return eval::InterruptRequested(); };
  slurm.job_name = "rephoto-sweep";
  slurm.skip_succeeded = false;  // the plans' keys say what is unfinished
  LogInfo(fmt::format("sweep on Slurm: {} settings, {} tasks ({} done before) -> {}",
                      plan.settings.size(), tasks + 1, done_before + (sweep_done ? 1 : 0),
                      options.out.string()));
  const cluster::RunOutcome run =
      cluster::RunTaskGroups(options.out, groups, slurm, cluster::ProgressLogger());
  result->slurm = run;
  for (const std::string& line : run.FailureLines()) LogWarning("slurm: failed: " + line);
  if (!run.finished) return false;
  CollectSettings(options, plan, result);
  return true;
}

// The geometric columns of sweep.csv (each setting's run against options.reference; cached in
// the run folder, so the report reads the same results back).
void AddGeometry(const SweepOptions& options, const std::vector<fs::path>& run_dirs,
                 SweepTable* table) {
  REPHOTO_CHECK(fs::is_regular_file(options.reference),
                "{}: the sweep's geometric reference does not exist or is not a file",
                options.reference.string());
  table->geometry_columns = geometry::RunGeometryColumns(options.geometry);
  for (size_t i = 0; i < table->settings.size() && i < run_dirs.size(); ++i) {
    if (!fs::exists(run_dirs[i] / "per_fold.csv")) continue;
    const geometry::RunGeometry g =
        geometry::EvaluateRunGeometry(run_dirs[i], options.reference, options.geometry);
    if (!g.available) LogWarning("sweep geometry: " + g.message);
    table->settings[i].geometry = geometry::RunGeometryValues(g, options.geometry);
  }
}

void WriteReport(const SweepOptions& options, const std::string& x_axis,
                 const SweepResult& result) {
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
  if (entries.empty()) return;
  report::CollectionOptions report_options;
  report_options.title = "rephoto sweep: " + options.out.filename().string();
  report_options.image_folders = {ReadBaseScene(options.base).image_root};  // the photos
  report_options.setting_name = x_axis;
  report_options.rank = false;
  report_options.geometry_reference = options.reference;
  report_options.geometry_options = options.geometry;
  report::WriteCollectionReport(entries, options.out / "report.html", report_options);
}

void WriteSweepJson(const SweepOptions& options, const std::string& x_axis,
                    const SweepResult& result) {
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
}

}  // namespace

SweepResult RunSweep(const SweepOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  SweepResult result;
  const SweepPlan plan = PlanSweep(options, &result);
  CheckSettings(options, plan);
  // One writer; only a folder that holds a sweep (or nothing). Each setting's evaluate run
  // locks its own folder below it. The aggregation task of a sweep on Slurm runs while the
  // submitting sweep holds the lock: it writes only the sweep's tables, report and sweep.json.
  run::RunFolder run_folder;
  if (!options.only_aggregate) {
    run_folder = run::OpenRunFolder(options.out, "sweep", [](const fs::path& dir) {
      std::error_code ec;
      return fs::exists(dir / "sweep.json", ec) || fs::is_directory(dir / "settings", ec);
    });
  }
  fs::create_directories(options.out / "settings");
  if (options.only_aggregate) {
    CollectSettings(options, plan, &result);
  } else if (options.base.executor == eval::Executor::kSlurm) {
    result.slurm_finished = RunSettingsOnSlurm(options, plan, &result);
    result.total_seconds = Seconds(start);
    return result;  // the tables, report and sweep.json come from the "sweep" task
  } else {
    RunSettings(options, plan, &result);
  }
  std::vector<fs::path> run_dirs;
  for (const SettingOutcome& outcome : result.settings) run_dirs.push_back(outcome.run_dir);
  result.table = ReadSweepTable(plan.settings, run_dirs);
  if (!options.reference.empty()) AddGeometry(options, run_dirs, &result.table);
  WriteTextFileAtomically(options.out / "sweep.csv", SweepSummaryCsv(result.table, result.axes));
  WriteTextFileAtomically(options.out / "sweep_per_fold.csv",
                          SweepPerFoldCsv(result.table, result.axes));
  if (options.report) WriteReport(options, plan.x_axis, result);
  result.total_seconds = Seconds(start);
  WriteSweepJson(options, plan.x_axis, result);
  return result;
}

}  // namespace rephoto::sweep
