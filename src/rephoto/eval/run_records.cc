#include "rephoto/eval/run_records.h"

#include <algorithm>

#include "rephoto/core/process.h"
#include "rephoto/eval/settings.h"

namespace rephoto::eval {
namespace fs = std::filesystem;
using run::JsonNumber;

void WriteViewRecord(const RunContext& s, const FoldPlan& fold, const ViewOutcome& outcome) {
  const compare::ImageResult& image = outcome.image;
  Json j;
  j["schema"] = "rephoto.evaluate.view/1";
  j["key"] = outcome.key;
  j["render_key"] = outcome.render_key.empty() ? Json() : Json(outcome.render_key);
  j["status"] = "ok";
  j["fold"] = fold.name;
  j["name"] = outcome.name;
  j["name_stem"] = image.name;
  j["photo"] = image.photo.string();
  j["render"] = image.render.generic_string();
  j["width"] = image.width;
  j["height"] = image.height;
  j["resized"] = image.resized;
  j["completeness"] = {{"value", JsonNumber(image.completeness.value)},
                       {"valid_photo_windows", image.completeness.valid_photo},
                       {"valid_both_windows", image.completeness.valid_both}};
  Json metrics_json = Json::object();
  for (size_t k = 0; k < s.options.metrics.size(); ++k) {
    metrics_json[std::string(metrics::MetricName(s.options.metrics[k]))] = {
        {"mean", JsonNumber(image.metrics[k].mean)}, {"evaluated", image.metrics[k].evaluated}};
  }
  j["metrics"] = metrics_json;
  if (s.options.compat) {
    const std::vector<metrics::Metric> compat = CompatMetrics(s.options);
    Json compat_json = Json::object();
    for (size_t k = 0; k < compat.size() && k < outcome.compat.size(); ++k) {
      compat_json[std::string(metrics::MetricName(compat[k]))] = {
          {"value", JsonNumber(outcome.compat[k].mean)},
          {"evaluated", outcome.compat[k].evaluated}};
    }
    j["compat"] = {{"preset", metrics::CompatPresetName(*s.options.compat)},
                   {"metrics", compat_json}};
  }
  j["render_seconds"] = outcome.render_seconds;
  j["compare_seconds"] = outcome.compare_seconds;
  run::WriteJsonRecord(outcome.record, j);
}

bool ReadViewRecord(const RunContext& s, const fs::path& path, const std::optional<Json>& json,
                    const std::string& key, ViewOutcome* outcome) {
  if (!json || json->value("key", "") != key || json->value("status", "") != "ok") return false;
  try {
    compare::ImageResult& image = outcome->image;
    image.name = json->at("name_stem").get<std::string>();
    image.photo = json->at("photo").get<std::string>();
    image.render = json->at("render").get<std::string>();
    image.width = json->at("width").get<int>();
    image.height = json->at("height").get<int>();
    image.resized = json->at("resized").get<bool>();
    const Json& c = json->at("completeness");
    image.completeness.value = run::NumberFromJson(c.at("value"));
    image.completeness.valid_photo = c.at("valid_photo_windows").get<size_t>();
    image.completeness.valid_both = c.at("valid_both_windows").get<size_t>();
    const Json& m = json->at("metrics");
    image.metrics.clear();
    for (metrics::Metric metric : s.options.metrics) {
      const Json& entry = m.at(std::string(metrics::MetricName(metric)));
      image.metrics.push_back(
          {run::NumberFromJson(entry.at("mean")), entry.at("evaluated").get<size_t>()});
    }
    outcome->compat.clear();
    if (s.options.compat) {
      const Json& c = json->at("compat").at("metrics");
      for (metrics::Metric metric : CompatMetrics(s.options)) {
        const Json& entry = c.at(std::string(metrics::MetricName(metric)));
        outcome->compat.push_back(
            {run::NumberFromJson(entry.at("value")), entry.at("evaluated").get<size_t>()});
      }
    }
    outcome->render_seconds = json->value("render_seconds", 0.0);
    outcome->compare_seconds = json->value("compare_seconds", 0.0);
  } catch (const std::exception&) {
    return false;
  }
  // The files the record points to must still be there; a record naming a rendering outside
  // the run folder (absolute, or with "..") is not this run's and is recomputed.
  const fs::path& render = outcome->image.render;
  if (render.is_absolute() || render.empty() ||
      render.lexically_normal().generic_string().rfind("..", 0) == 0) {
    return false;
  }
  std::error_code ec;
  if (!fs::exists(s.run / render, ec)) return false;
  if (s.options.error_images) {
    for (metrics::Metric metric : WrittenErrorImageMetrics(s.options)) {
      const std::string base = outcome->stem + "." + std::string(metrics::MetricName(metric));
      if (!fs::exists(path.parent_path().parent_path() / "errors" / (base + ".exr"), ec)) {
        return false;
      }
    }
  }
  return true;
}

void WriteFoldJson(const RunContext& s, const FoldPlan& plan, const FoldOutcome& fold,
                   const std::string& status) {
  const CommandOutcome& command = fold.command;
  const FoldModel& model = fold.model;
  Json j;
  j["schema"] = "rephoto.evaluate.fold/1";
  j["fold"] = plan.name;
  j["index"] = plan.index;
  j["status"] = status;
  j["message"] = fold.message;
  if (s.source != ModelSource::kModel) {
    j["command"] = {{"kind", s.CommandKind()},
                    {"key", command.key},
                    {"status", command.status},
                    {"seconds", command.seconds},
                    {"cpu_seconds", command.cpu_seconds},
                    {"reused", command.reused},
                    {"command", command.command},
                    {"log", s.Relative(plan.log_file)}};
  }
  j["model"] = model.path.empty() ? Json() : Json(model.path.string());
  j["model_key"] = model.model_key;
  j["colorize_key"] = model.colorize_key;
  if (s.DerivesModel()) {
    j["colorized_model"] = plan.derived_model.lexically_relative(plan.dir).generic_string();
  }
  j["train"] = {{"folder", plan.train_dir.string()},
                {"images", plan.images_dir.string()},
                {"count", plan.train_names.size()},
                {"key", plan.train_key}};
  j["test"] = {{"folder", plan.test_dir.string()}, {"count", plan.tests.size()}};
  size_t evaluated = 0;
  double view_seconds = 0;
  for (const ViewOutcome& v : fold.views) {
    evaluated += v.ok ? 1 : 0;
    view_seconds += v.render_seconds + v.compare_seconds;
  }
  j["test_images"] = plan.tests.size();
  j["evaluated_images"] = evaluated;
  j["seconds"] = {{"command", command.seconds},
                  {"colorize", model.colorize_seconds},
                  {"views", view_seconds},
                  {"this_run", fold.seconds}};
  run::WriteJsonRecord(plan.dir / "fold.json", j);
}

namespace {

Json InputsJson(const RunContext& s, const std::vector<FoldPlan>& plans) {
  Json inputs;
  inputs["scene"] = {{"path", fs::absolute(s.options.scene).lexically_normal().string()},
                     {"format", std::string(scene::SceneFormatName(s.scene_source.format))},
                     {"source", fs::absolute(s.scene_source.path).lexically_normal().string()},
                     {"image_root", fs::absolute(s.scene.image_root).lexically_normal().string()},
                     {"views", s.scene.views.size()}};
  if (s.source == ModelSource::kModel && !s.options.model.empty()) {
    std::string model_hash;
    try {
      model_hash = s.hashes->Hash(s.options.model);
    } catch (const Error&) {
    }
    inputs["model"] = {{"path", fs::absolute(s.options.model).lexically_normal().string()},
                       {"hash", model_hash}};
  }
  Json photos = Json::array();
  for (const FoldPlan& fold : plans) {
    for (const TestView& test : fold.tests) {
      photos.push_back(
          {{"name", test.name}, {"path", test.photo.string()}, {"hash", test.photo_hash}});
    }
  }
  std::sort(photos.begin(), photos.end(),
            [](const Json& a, const Json& b) { return a["name"] < b["name"]; });
  photos.erase(std::unique(photos.begin(), photos.end()), photos.end());
  inputs["photos"] = photos;
  inputs["hash"] = "xxh3-64 of the file content";
  Json missing = Json::array();
  for (const std::string& name : s.missing_photos) missing.push_back(name);
  inputs["missing_photos"] = missing;
  return inputs;
}

Json SplitJson(const RunContext& s, const std::vector<FoldPlan>& plans) {
  Json split_json;
  split_json["scheme"] = s.split.scheme.ToString();
  split_json["cross_validated"] = s.split.cross_validated;
  split_json["folder"] = "split";
  Json folds = Json::array();
  for (size_t f = 0; f < s.split.folds.size() && f < plans.size(); ++f) {
    folds.push_back({{"fold", plans[f].name},
                     {"train", plans[f].train_names},
                     {"test", s.split.folds[f].test}});
  }
  split_json["folds"] = folds;
  return split_json;
}

Json TimingsJson(const RunContext& s, const EvaluateTimings& t) {
  const double rephoto_cpu = ProcessCpuSeconds() - s.start_cpu;
  return {{"total", Seconds(s.start)},
          {"external", t.external},
          {"cpu",
           {{"external", t.external_cpu},
            {"rephoto", rephoto_cpu},
            {"rephoto_share", RephotoShare(rephoto_cpu, t.external_cpu)}}},
          {"rephoto",
           {{"total", t.rephoto()},
            {"split", t.split},
            {"prepare", t.prepare},
            {"colorize", t.colorize},
            {"render", t.render},
            {"photos", t.photos},
            {"compare", t.compare},
            {"write", t.write},
            {"views", t.views},
            {"aggregate", t.aggregate},
            {"project", t.project},
            {"report", t.report}}},
          {"note",
           "seconds of this invocation; external = sum over commands, which run in "
           "background threads and may overlap rephoto's own work (wall-clock sums "
           "then count the overlap twice); cpu = user + system CPU seconds of the "
           "commands' process trees and of rephoto's own process; the views' render, photos, "
           "compare and "
           "write run in a pipeline (one view is compared while the next is rendered and the "
           "previous one written), so their sum can exceed views, the view stage's wall time"}};
}

Json OutputsJson(const RunContext& s, const RunStatus& status) {
  Json projected = Json::array();
  std::error_code ec;
  for (fs::directory_iterator it(s.run / "projected", ec), end; !ec && it != end;
       it.increment(ec)) {
    if (it->path().extension() == ".ply") projected.push_back(s.Relative(it->path()));
  }
  std::sort(projected.begin(), projected.end());
  return {{"projected", projected},
          {"projection_error",
           status.projection_message.empty() ? Json() : Json(status.projection_message)},
          {"report", fs::exists(s.run / "report.html", ec) ? Json("report.html") : Json()},
          {"report_error", status.report_message.empty() ? Json() : Json(status.report_message)}};
}

}  // namespace

void WriteRunJson(const RunContext& s, const std::vector<FoldPlan>& plans, const Tally& tally,
                  const RunStatus& run_status, const EvaluateResult* result,
                  const std::string& status) {
  Json j;
  j["schema"] = kSchema;
  j["tool"] = {{"name", "rephoto"}, {"version", compare::ToolVersion()}};
  j["status"] = status;
  if (!run_status.failure.empty()) j["error"] = run_status.failure;
  Json command_line = Json::array();
  for (const std::string& arg : s.options.command_line) command_line.push_back(arg);
  j["command_line"] = command_line;
  j["config_file"] = s.options.config_file.empty() ? Json() : Json(s.options.config_file.string());
  j["settings"] = SettingsJson(s.options);
  j["scene_identity"] = s.scene_identity;
  j["inputs"] = InputsJson(s, plans);
  j["split"] = SplitJson(s, plans);
  j["timings"] = TimingsJson(s, tally.timings());
  const EvaluateCounters c = tally.counters();
  j["counters"] = {{"commands_run", c.commands_run},           {"folds_reused", c.folds_reused},
                   {"models_colorized", c.models_colorized},   {"views_rendered", c.views_rendered},
                   {"views_compared", c.views_compared},       {"views_reused", c.views_reused},
                   {"photos_downscaled", c.photos_downscaled}, {"projections", c.projections}};
  Json fold_status = Json::array();
  if (result != nullptr) {
    for (const FoldResult& fr : result->folds) {
      fold_status.push_back({{"fold", fr.name},
                             {"status", fr.ok ? "ok" : "failed"},
                             {"message", fr.message},
                             {"test_images", fr.test_images},
                             {"evaluated_images", fr.evaluated_images},
                             {"seconds", fr.seconds}});
    }
  }
  j["folds"] = fold_status;
  j["outputs"] = OutputsJson(s, run_status);
  run::WriteJsonRecord(s.run / "run.json", j);
}

namespace {

Json ViewTaskJson(const RunContext& s, const FoldPlan& fold, const FoldOutcome& fold_outcome,
                  size_t i, const std::string& command_id) {
  const TestView& test = fold.tests[i];
  const ViewOutcome* outcome = i < fold_outcome.views.size() ? &fold_outcome.views[i] : nullptr;
  Json outputs = {{"record", s.Relative(fold.dir / "views" / (test.stem + ".json"))}};
  if (s.source != ModelSource::kRender) {
    outputs["render"] = s.Relative(fold.dir / "renders" / (test.stem + ".png"));
    // (A Gaussian model's folds write no depth maps: WritesDepthImages.)
    if (WritesDepthImages(s.options, /*gaussians=*/false)) {
      outputs["depth"] = s.Relative(fold.dir / "renders" / (test.stem + ".depth.exr"));
    }
  }
  if (s.options.error_images) {
    Json errors = Json::array();
    for (metrics::Metric m : WrittenErrorImageMetrics(s.options)) {
      errors.push_back(s.Relative(
          fold.dir / "errors" / (test.stem + "." + std::string(metrics::MetricName(m)) + ".exr")));
    }
    outputs["errors"] = errors;
  }
  Json camera_params = Json::array();
  for (double p : test.camera.params) camera_params.push_back(p);
  return {{"id", fold.name + "/" + test.stem},
          {"kind", "view"},
          {"fold", fold.name},
          {"view", test.name},
          {"key", outcome && !outcome->key.empty() ? Json(outcome->key) : Json()},
          {"inputs",
           {{"photo", test.photo.string()},
            {"photo_hash", test.photo_hash},
            {"mask", test.mask.empty() ? Json() : Json(test.mask.string())},
            {"model",
             fold_outcome.model.path.empty() ? Json() : Json(fold_outcome.model.path.string())},
            {"camera",
             {{"model", std::string(camera::CameraModelName(test.camera.model))},
              {"width", test.camera.width},
              {"height", test.camera.height},
              {"params", camera_params}}}}},
          {"outputs", outputs},
          {"depends_on", command_id.empty() ? Json::array() : Json::array({command_id})},
          {"status", outcome && outcome->ok ? "done" : "pending"}};
}

}  // namespace

void WriteManifest(const RunContext& s, const std::vector<FoldPlan>& plans,
                   const std::vector<FoldOutcome>& outcomes) {
  Json tasks = Json::array();
  for (size_t f = 0; f < plans.size(); ++f) {
    const FoldPlan& fold = plans[f];
    std::string command_id;
    if (s.source != ModelSource::kModel) {
      command_id = fold.name + "/" + s.CommandKind();
      tasks.push_back({{"id", command_id},
                       {"kind", s.CommandKind()},
                       {"fold", fold.name},
                       {"key", outcomes[f].command.key},
                       {"command", outcomes[f].command.command},
                       {"inputs",
                        {{"train", fold.train_dir.string()},
                         {"images", fold.images_dir.string()},
                         {"test", fold.test_dir.string()}}},
                       {"outputs", {{"folder", s.Relative(fold.out_dir)}}},
                       {"log", s.Relative(fold.log_file)},
                       {"depends_on", Json::array()}});
    }
    for (size_t i = 0; i < fold.tests.size(); ++i) {
      tasks.push_back(ViewTaskJson(s, fold, outcomes[f], i, command_id));
    }
  }
  Json manifest;
  manifest["schema"] = "rephoto.evaluate.manifest/1";
  manifest["run"] = fs::absolute(s.run).lexically_normal().string();
  manifest["note"] =
      "Independent tasks: a view task needs only its fold's command task. Running a task "
      "elsewhere and copying its outputs (record last) into RUN lets `rephoto evaluate` with "
      "the same settings reuse it.";
  manifest["tasks"] = tasks;
  run::WriteJsonRecord(s.run / "manifest.json", manifest);
}

}  // namespace rephoto::eval
