#include "rephoto/demo/demo.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <future>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "rephoto/compare/compare.h"
#include "rephoto/core/background_worker.h"
#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/degrade/degrade.h"
#include "rephoto/degrade/simplex_noise.h"
#include "rephoto/io/csv.h"
#include "rephoto/io/image_io.h"
#include "rephoto/mesh/mesh.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/render/render.h"
#include "rephoto/render/view_renderer.h"
#include "rephoto/report/report.h"
#include "rephoto/scene/colmap.h"
#include "rephoto/suggest/suggest_page.h"
#include "rephoto/suggest/suggest_run.h"

namespace rephoto::demo {
namespace fs = std::filesystem;
namespace {

std::string Stem(const std::string& name) { return fs::path(name).stem().string(); }

mesh::Mesh PointCloudFrom(const mesh::Mesh& truth, size_t step) {
  mesh::Mesh cloud;
  for (size_t v = 0; v < truth.positions.size(); v += step) {
    cloud.positions.push_back(truth.positions[v]);
    cloud.colors.push_back(truth.colors[v]);
    cloud.normals.push_back(truth.normals[v]);
  }
  return cloud;
}

struct Recipe {
  std::string name, description;
  mesh::Mesh model;
  render::ViewRepresentation representation = render::ViewRepresentation::kAuto;
};

// Photos: the ground truth, finely anti-aliased, with exposure differences and sensor noise,
// and the masks of what each photo shows of the scene. A background thread writes each view's
// two PNGs while the next view renders (PNG encoding is single-threaded); at most one view
// waits to be written.
void Photograph(const DemoOptions& options, const mesh::Mesh& truth, const scene::Scene& scene,
                const fs::path& images_dir, const fs::path& masks_dir) {
  const std::string task = "demo: photographing";
  render::RenderModel model(truth, {}, task);
  render::RenderOptions render_options;
  render_options.samples_per_pixel = options.photo_samples_per_pixel;
  uint64_t state = options.scene.seed ^ 0xF070ULL;
  render::Rephoto clean;
  Progress progress(task, scene.views.size());
  BackgroundWorker writer;
  std::future<void> written;
  for (size_t i = 0; i < scene.views.size(); ++i) {
    const scene::View& view = scene.views[i];
    render::RenderRephoto(model, *model.RaysFor(scene.CameraOf(view)), view.cam_from_world,
                          render_options, &clean);
    const double gain =
        1.0 + options.max_exposure_change * (2 * degrade::UniformDouble(state) - 1);
    auto photo = std::make_shared<Image>(synth::SimulatePhoto(
        clean.color, gain, options.noise_sigma, options.scene.seed * 1000 + i));
    // The user's mask of what the photo shows of the scene (not the empty sky), as people mask
    // the sky or background of real photos: completeness then measures how much of the scene a
    // reconstruction covers.
    auto mask = std::make_shared<Mask>(clean.color.width(), clean.color.height(), 1);
    for (size_t p = 0; p < mask->pixel_count(); ++p) {
      mask->data()[p] = clean.color.data()[4 * p + 3] >= 1.f ? 1 : 0;
    }
    if (written.valid()) written.get();  // rethrows a failed write
    written = writer.Submit([photo, mask, image_path = images_dir / view.name,
                             mask_path = masks_dir / (Stem(view.name) + ".png")] {
      io::WritePng(image_path, *photo);
      io::WritePng(mask_path, *mask);
    });
    progress.Advance(view.name);
  }
  if (written.valid()) written.get();
}

// The six reconstructions the demo ranks, each made from the ground truth.
std::vector<Recipe> MakeRecipes(const DemoOptions& options, const mesh::Mesh& truth) {
  std::vector<Recipe> recipes;
  recipes.push_back({"ground_truth", "the ground-truth mesh with vertex colours", truth});
  degrade::DegradeOptions d;
  d.seed = options.scene.seed;
  d.texture_noise = 0.15f;
  recipes.push_back({"texture_noise", "vertex colours offset by simplex noise (max 0.15)",
                     degrade::Degrade(truth, d)});
  d = {};
  d.seed = options.scene.seed;
  d.geometry_noise = 0.002f;
  recipes.push_back({"geometry_noise",
                     "vertices moved along normals by simplex noise (max 0.2 % of the extent)",
                     degrade::Degrade(truth, d)});
  d = {};
  d.simplify = 0.97f;
  recipes.push_back(
      {"simplified", "97 % of the vertices removed by edge collapse", degrade::Degrade(truth, d)});
  recipes.push_back({"point_cloud",
                     "every 3rd vertex as an oriented disc, radius from the point density",
                     PointCloudFrom(truth, 3)});
  // The paper's Table I: view-dependent texturing makes a coarse proxy look good again.
  recipes.push_back({"view_dependent",
                     "the simplified mesh textured view-dependently from each fold's training "
                     "photos (Buehler et al. 2001)",
                     std::find_if(recipes.begin(), recipes.end(),
                                  [](const Recipe& r) { return r.name == "simplified"; })
                         ->model,
                     render::ViewRepresentation::kVdt});
  return recipes;
}

// Writes the recipe's model (the view-dependent one reuses the simplified proxy written before
// it) and evaluates it in runs/<name>.
DemoReconstruction EvaluateRecipe(const DemoOptions& options, const Recipe& recipe,
                                  const fs::path& scene_dir, const fs::path& images_dir,
                                  const fs::path& masks_dir) {
  fs::path model_path = options.out / "models" / (recipe.name + ".ply");
  if (recipe.representation == render::ViewRepresentation::kAuto) {
    mesh::WritePly(model_path, recipe.model);
  } else {
    model_path = options.out / "models" / "simplified.ply";  // the proxy, written above
  }
  eval::EvaluateOptions e;
  e.scene = scene_dir / "sparse";
  e.format = "colmap";
  e.image_root = images_dir;
  e.photo_masks = masks_dir;
  e.scheme = options.scheme;
  e.model = model_path;
  e.representation = recipe.representation;
  e.metrics = options.metrics;
  // Error images of 1-NCC only (the reports show them, the projection reads them): all eight
  // metrics' would be 5 GB for the demo's 96 views.
  e.error_image_metrics = {metrics::Metric::kOneMinusNcc};
  e.samples_per_pixel = options.render_samples_per_pixel;
  e.report = options.report;
  e.out = options.out / "runs" / recipe.name;
  e.command_line = {"rephoto", "demo"};
  LogInfo("demo: evaluating " + recipe.name);
  DemoReconstruction r{.name = recipe.name,
                       .description = recipe.description,
                       .model = model_path,
                       .run_dir = e.out,
                       .result = eval::RunEvaluate(e)};
  REPHOTO_CHECK(r.result.exit_code == ExitCode::kOk, "demo: the evaluation of {} is incomplete",
                recipe.name);
  return r;
}

// ranking.csv and the ranking part of demo.json, in rank order.
void AddRanking(const DemoOptions& options, const DemoResult& result, io::CsvWriter& csv,
                nlohmann::ordered_json& json) {
  std::vector<std::string> header = {"rank", "reconstruction", "completeness_median"};
  for (metrics::Metric m : options.metrics) {
    header.push_back(std::string(metrics::MetricName(m)) + "_median");
  }
  header.push_back("description");
  csv.AddRow(header);
  for (size_t rank = 0; rank < result.ranking.size(); ++rank) {
    const auto& r = result.ranking[rank];
    std::vector<std::string> row = {std::to_string(rank + 1), r.name,
                                    io::CsvNumber(r.result.completeness_across_folds.median)};
    nlohmann::ordered_json entry;
    entry["rank"] = rank + 1;
    entry["reconstruction"] = r.name;
    entry["description"] = r.description;
    entry["model"] = r.model.string();
    entry["run"] = r.run_dir.string();
    entry["completeness_median"] = r.result.completeness_across_folds.median;
    for (metrics::Metric m : options.metrics) {
      const double v = r.Median(m);
      row.push_back(io::CsvNumber(v));
      entry[std::string(metrics::MetricName(m)) + "_median"] =
          std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json(nullptr);
    }
    row.push_back(r.description);
    csv.AddRow(row);
    json["ranking"].push_back(entry);
  }
}

// Step 4: the photos of one half of the ring only, and the views `rephoto suggest` proposes to
// take next (see demo.h).
DemoSuggestions SuggestNextPhotos(const DemoOptions& options, const mesh::Mesh& truth,
                                  const scene::Scene& scene) {
  const std::array<Eigen::Vector3f, 2> box = mesh::BoundingBox(truth);
  const double middle = 0.5 * (box[0].x() + box[1].x());
  scene::Scene one_side = scene;
  one_side.views.clear();
  for (const scene::View& view : scene.views) {
    if (view.cam_from_world.Center().x() > middle) one_side.views.push_back(view);
  }
  REPHOTO_CHECK(!one_side.views.empty() && one_side.views.size() < scene.views.size(),
                "demo: the acquisition step needs cameras on both sides of the object ({} of {} "
                "on one side)",
                one_side.views.size(), scene.views.size());
  DemoSuggestions outcome;
  outcome.folder = options.out / "next_photos";
  outcome.photos_so_far = one_side.views.size();
  const fs::path so_far = outcome.folder / "photos_so_far" / "sparse";
  fs::create_directories(so_far);
  scene::WriteColmap(one_side, so_far, scene::ColmapFormat::kText);
  suggest::SuggestRunOptions run;
  run.out = outcome.folder;
  run.scene_label = so_far.string();
  run.model_label = (options.out / "models" / "ground_truth.ply").string();
  run.suggest.count = options.suggestions;
  // The ground truth's projected 1-NCC (its evaluation above, on the same vertices): without
  // it the suggestions have no "mean error" (only the surface no photo sees counts).
  const fs::path truth_run = options.out / "runs" / "ground_truth";
  std::error_code ec;
  if (fs::is_regular_file(truth_run / "projected" / "1-ncc.ply", ec)) run.run = truth_run;
  LogInfo(fmt::format("demo: suggesting {} views to add to the {} photos from one side",
                      options.suggestions, one_side.views.size()));
  const render::RenderModel model(truth, {}, run.model_label);
  const suggest::SuggestResult result = suggest::RunSuggest(one_side, model, run);
  LogInfo("demo: " + suggest::SuggestSummary(result, run));
  outcome.unseen_fraction =
      result.total_area > 0 ? result.unobserved_area / result.total_area : 0.0;
  outcome.covered_fraction =
      result.unobserved_area > 0 ? result.unobserved_area_covered / result.unobserved_area : 0.0;
  return outcome;
}

void WriteDemoReport(const DemoOptions& options, const DemoResult& result) {
  std::vector<report::CollectionEntry> entries;
  for (const auto& r : result.ranking) {
    entries.push_back({.label = r.name, .description = r.description, .run_dir = r.run_dir});
  }
  report::CollectionOptions report_options;
  report_options.title = "rephoto demo: six reconstructions of the procedural scene";
  // The photos, and the models (their colours in the 3D view).
  report_options.image_folders = {options.out / "scene" / "images", options.out / "models"};
  if (result.suggestions) report_options.suggestions = result.suggestions->folder;
  if (result.suggestions) {
    report_options.sections.push_back(
        {.id = "next-photos",
         .title = "Where to photograph next",
         .note = fmt::format(
        "Had only the {} photos from one side of the ring been taken, {:.1f} % of the model's "
        "surface would be seen by no photo. rephoto suggest proposes these views to take next: "
        "together they see {:.1f} % of that surface. (`rephoto suggest --scene "
        "next_photos/photos_so_far/sparse --model models/ground_truth.ply --out next_photos`)",
             result.suggestions->photos_so_far, 100 * result.suggestions->unseen_fraction,
             100 * result.suggestions->covered_fraction),
         .body_html = suggest::SuggestionsSectionHtml(result.suggestions->folder,
                                                      report_options.thumbnail_width, 3)});
  }
  report::WriteCollectionReport(entries, options.out / "report.html", report_options);
}

}  // namespace

double DemoReconstruction::Median(metrics::Metric metric) const {
  for (const auto& m : result.metrics) {
    if (m.metric == metric) return m.across_folds.median;
  }
  return std::nan("");
}

DemoResult RunDemo(const DemoOptions& options) {
  REPHOTO_CHECK(!options.out.empty(), "demo: no output folder given");
  const auto start = std::chrono::steady_clock::now();
  const fs::path scene_dir = options.out / "scene";
  const fs::path images_dir = scene_dir / "images";
  const fs::path masks_dir = scene_dir / "masks";

  LogInfo(fmt::format("demo: generating the procedural scene ({} cameras, {}x{} photos)",
                      options.scene.camera_count, options.scene.image_width,
                      options.scene.image_height));
  const mesh::Mesh truth = synth::MakeDemoMesh(options.scene);
  const scene::Scene scene = synth::MakeDemoScene(options.scene, images_dir);
  mesh::WritePly(scene_dir / "ground_truth.ply", truth);
  scene::WriteColmap(scene, scene_dir / "sparse", scene::ColmapFormat::kText);
  Photograph(options, truth, scene, images_dir, masks_dir);

  DemoResult result;
  for (const Recipe& recipe : MakeRecipes(options, truth)) {
    result.ranking.push_back(EvaluateRecipe(options, recipe, scene_dir, images_dir, masks_dir));
  }
  std::stable_sort(result.ranking.begin(), result.ranking.end(), [](const auto& a, const auto& b) {
    return a.Median(metrics::Metric::kOneMinusNcc) < b.Median(metrics::Metric::kOneMinusNcc);
  });
  if (options.suggestions > 0) result.suggestions = SuggestNextPhotos(options, truth, scene);

  io::CsvWriter csv;
  nlohmann::ordered_json json;
  json["schema"] = "rephoto.demo/2";
  json["tool_version"] = compare::ToolVersion();
  json["photos"] = images_dir.string();
  json["cameras"] = scene.views.size();
  json["image_size"] = {options.scene.image_width, options.scene.image_height};
  json["scheme"] = options.scheme;
  json["ranked_by"] = "median across folds of the fold means of 1-ncc";
  AddRanking(options, result, csv, json);
  if (result.suggestions) {
    json["next_photos"] = {{"folder", result.suggestions->folder.string()},
                           {"photos_so_far", result.suggestions->photos_so_far},
                           {"suggested", options.suggestions},
                           {"unseen_fraction", result.suggestions->unseen_fraction},
                           {"covered_fraction", result.suggestions->covered_fraction}};
  }
  if (options.report) WriteDemoReport(options, result);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  json["seconds"] = result.seconds;
  WriteTextFileAtomically(options.out / "ranking.csv", csv.text());
  WriteTextFileAtomically(options.out / "demo.json", json.dump(2) + "\n");
  return result;
}

}  // namespace rephoto::demo
