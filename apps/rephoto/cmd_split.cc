// rephoto split SCENE --scheme S --out DIR [--format F] [--image-root DIR]
// Splits a scene's photos into training and test sets (rephoto/split/split.h) and writes per
// fold the lists, a COLMAP text model and transforms.json of the training views and of the
// test cameras, plus DIR/split.json (rephoto/split/split_writer.h).
#include <fmt/format.h>

#include <memory>
#include <string>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/split/split.h"
#include "rephoto/split/split_writer.h"
#include "scene_args.h"

namespace rephoto::cli {
namespace {

struct SplitArguments {
  std::string scene;
  std::string scheme;
  std::string out;
  SceneArguments scene_args;
};

CommandRunner SetupSplit(CLI::App& app) {
  auto args = std::make_shared<SplitArguments>();
  app.add_option("scene", args->scene, "Scene file or folder (format detected)")->required();
  app.add_option("--scheme", args->scheme,
                 "kfold:K[:SEED] (seeded shuffle; a fold may hold out neighbours) | interleaved:K "
                 "(image i by name tested in fold i mod K) | loo | every:N (test iff index % N == "
                 "0, sorted by name) | "
                 "fraction:F[:SEED] | lists:TRAIN,TEST | none")
      ->required();
  app.add_option("--out", args->out, "Output folder (fold_XX/..., split.json)")->required();
  AddSceneOptions(app, &args->scene_args);
  return [args]() {
    const split::Scheme scheme = split::ParseScheme(args->scheme);
    const scene::ReadSceneOptions options = MakeReadSceneOptions(args->scene_args);
    scene::SceneSource source;
    const scene::Scene scene = scene::ReadScene(args->scene, options, &source);
    std::vector<std::string> names;
    for (const scene::View& view : scene.views) names.push_back(view.name);
    const split::Split split = split::MakeSplit(names, scheme);
    split::WriteSplit(scene, split,
                      {args->scene, std::string(scene::SceneFormatName(source.format))}, args->out);
    size_t tests = 0;
    for (const split::Fold& fold : split.folds) tests += fold.test.size();
    LogInfo(fmt::format("{}: {} images, {} fold(s), {} test images in total{} -> {}", args->scene,
                        names.size(), split.folds.size(), tests,
                        split.cross_validated ? "" : " (not cross-validated: train = test)",
                        args->out));
    const auto missing = scene::MissingImages(scene);
    if (!missing.empty()) {
      LogWarning(fmt::format("{} of {} images are missing on disk (first: {})", missing.size(),
                             names.size(), missing.front()));
    }
    return static_cast<int>(ExitCode::kOk);
  };
}

}  // namespace

REPHOTO_COMMAND(11, "split", "Split a scene's photos into training and test folds", SetupSplit);

}  // namespace rephoto::cli
