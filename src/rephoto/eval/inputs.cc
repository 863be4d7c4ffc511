#include "rephoto/eval/inputs.h"

#include <algorithm>
#include <set>

#include "rephoto/core/progress.h"
#include "rephoto/eval/run_records.h"
#include "rephoto/scene/image_name.h"
#include "rephoto/split/split.h"
#include "rephoto/split/split_writer.h"

namespace rephoto::eval {
namespace fs = std::filesystem;

void ReadInputs(RunContext& s) {
  scene::ReadSceneOptions read_options;
  if (!s.options.format.empty()) {
    read_options.format = scene::ParseSceneFormat(s.options.format);
    if (!read_options.format) {
      throw UsageError(fmt::format("--format '{}': unknown format (supported: {})", s.options.format,
                                   scene::SceneFormatList()));
    }
  }
  if (!s.options.image_root.empty()) read_options.image_root = s.options.image_root;
  s.scene = scene::ReadScene(s.options.scene, read_options, &s.scene_source);
  s.missing_photos = scene::MissingImages(s.scene);
  const std::set<std::string> missing(s.missing_photos.begin(), s.missing_photos.end());
  for (size_t v = 0; v < s.scene.views.size(); ++v) {
    const scene::View& view = s.scene.views[v];
    s.view_index[view.name] = v;
    if (missing.count(view.name)) {
      if (!s.worker) {
        LogWarning(fmt::format("{}: photo {} not found: view '{}' left out of the evaluation",
                               s.options.scene.string(), view.image_path.string(), view.name));
      }
    } else {
      s.photo_names.push_back(view.name);
    }
  }
  REPHOTO_CHECK(!s.photo_names.empty(), "{}: none of the {} photos exists (image root {})",
                s.options.scene.string(), s.scene.views.size(), s.scene.image_root.string());
  const std::vector<std::string> stems = scene::OutputStems(s.scene);
  for (size_t v = 0; v < s.scene.views.size(); ++v) s.stems[s.scene.views[v].name] = stems[v];
}

void OpenRun(RunContext& s, const Tally& tally, RunStatus& status) {
  // One writer, and only a folder that holds an evaluate run or nothing (run/run_folder.h);
  // folders from before the mark are recognised by their run.json.
  if (!s.worker) {
    status.run_folder = run::OpenRunFolder(s.run, "evaluate", [](const fs::path& dir) {
      std::error_code exists_ec;
      return fs::exists(dir / "run.json", exists_ec);
    });
  }
  // Identity of the scene: the set of its image names.
  std::vector<std::string> names;
  for (const scene::View& view : s.scene.views) names.push_back(view.name);
  std::sort(names.begin(), names.end());
  Hasher h;
  for (const std::string& name : names) h.Add(name);
  const std::string identity = h.Hex();
  const fs::path run_json = s.run / "run.json";
  std::error_code ec;
  REPHOTO_CHECK(!s.worker || fs::exists(run_json, ec),
                "{}: no run.json: the run folder was not prepared by `rephoto evaluate` (a task "
                "given with --only runs inside a prepared run)",
                s.run.string());
  if (fs::exists(run_json, ec)) {
    const std::optional<Json> previous = run::ReadJsonRecord(run_json);
    REPHOTO_CHECK(previous && previous->contains("scene_identity"),
                  "{}: not a rephoto evaluate run (unreadable run.json); use another --out",
                  run_json.string());
    const Json& old = (*previous)["scene_identity"];
    REPHOTO_CHECK(old.value("names_hash", "") == identity,
                  "{}: holds a run of another scene ({}, {} images; this scene {} has {} "
                  "images with other names); use another --out or delete it",
                  s.run.string(), old.value("scene", "?"), old.value("images", 0),
                  s.options.scene.string(), names.size());
  }
  s.scene_identity = {{"scene", fs::absolute(s.options.scene).lexically_normal().string()},
                      {"format", std::string(scene::SceneFormatName(s.scene_source.format))},
                      {"images", names.size()},
                      {"names_hash", identity}};
  s.hashes = std::make_unique<FileHashCache>(s.CacheDir() / "file_hashes.json");
  if (s.worker) return;
  // Marks the folder as this scene's run from now on.
  WriteRunJson(s, /*plans=*/{}, tally, status, nullptr, "running");
  status.run_json_ours = true;
}

void MakeSplit(RunContext& s) {
  s.scheme_text = ResolvedScheme(s.options, s.photo_names.size());
  const split::Scheme scheme = split::ParseScheme(s.scheme_text);  // UsageError when bad
  if (scheme.kind == split::SchemeKind::kLeaveOneOut || scheme.kind == split::SchemeKind::kKFold ||
      scheme.kind == split::SchemeKind::kInterleaved) {
    REPHOTO_CHECK(s.photo_names.size() >= 2, "{}: {} needs at least 2 photos, found {}",
                  s.options.scene.string(), s.scheme_text, s.photo_names.size());
  }
  s.split = split::MakeSplit(s.photo_names, scheme);
  if (s.worker) return;
  const scene::Scene with_photos =
      split::SubsetScene(s.scene, s.photo_names, /*keep_points=*/true);
  split::WriteSplit(
      with_photos, s.split,
      {s.options.scene.string(), std::string(scene::SceneFormatName(s.scene_source.format))},
      s.run / "split");
}

}  // namespace rephoto::eval
