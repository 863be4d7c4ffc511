// rephoto benchmark add-dataset --root DIR --name NAME --scene SCENE [--image-root DIR]
//                               --scheme every:N|fraction:F|lists:TRAIN,TEST [--shortcut PATH]...
//                               [--description TEXT] [--metrics LIST] [--headline METRIC]
//                               [--window N] [--eval-short-side PX] [--photo-masks DIR]
//                               [--ranking filled|min-completeness:F] [--public-fraction F]
// rephoto benchmark add-participant --root DIR --name NAME   (prints the token on the last line)
// rephoto benchmark revoke --root DIR --name NAME
// rephoto benchmark reveal --root DIR --name DATASET   (the private test photos rank)
// rephoto benchmark list --root DIR
// Administration of a benchmark folder (rephoto/service/): safe while `rephoto serve` runs on
// the same folder (SQLite WAL and busy timeout, see store.h).
#include <fmt/format.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "command.h"
#include "rephoto/service/dataset.h"
#include "rephoto/service/store.h"
#include "rephoto/service/text.h"
#include "rephoto/core/error.h"
#include "rephoto/core/progress.h"
#include "rephoto/metrics/metrics.h"
#include "scene_args.h"

namespace rephoto::cli {
namespace {

struct BenchmarkArguments {
  std::string root;
  std::string name;
  std::string description;
  std::string scene;
  SceneArguments scene_args;
  std::string scheme;
  std::vector<std::string> shortcuts;
  std::string metrics = "all";
  std::string headline = "1-ncc";
  int window = 9;
  int eval_short_side = 0;
  std::string photo_masks;
  std::string ranking = "filled";
  double public_fraction = 1;
};

void AddRootAndName(CLI::App* app, BenchmarkArguments* args, const std::string& what) {
  app->add_option("--root", args->root, "The benchmark folder")->required();
  app->add_option("--name", args->name, what)->required();
}

int RunAddDataset(const BenchmarkArguments& args) {
  std::filesystem::create_directories(args.root);
  service::Store store(args.root);
  service::DatasetOptions options;
  options.name = args.name;
  options.description = args.description;
  options.scene = args.scene;
  options.read_options = MakeReadSceneOptions(args.scene_args);
  options.scheme = args.scheme;
  for (const std::string& shortcut : args.shortcuts) options.shortcuts.push_back(shortcut);
  options.metrics = metrics::ParseMetricList(args.metrics);
  options.headline = args.headline;
  options.window = args.window;
  options.ranking = args.ranking;
  options.public_fraction = args.public_fraction;
  REPHOTO_CHECK_USAGE(service::IsCleanText(args.description, service::TextPolicy::kMultiLine),
                      "--description: not UTF-8 text without control characters");
  options.eval_short_side = args.eval_short_side;
  options.photo_masks = args.photo_masks;
  service::AddDataset(store, options);
  const auto dataset = store.FindDataset(args.name);
  LogInfo(fmt::format("dataset '{}': {} training photos, {} test cameras (photos kept secret)",
                      args.name, dataset->info.at("training_images").size(),
                      dataset->info.at("test_images").size()));
  return static_cast<int>(ExitCode::kOk);
}

int RunList(const BenchmarkArguments& args) {
  service::Store store(args.root);
  for (const auto& dataset : store.Datasets()) {
    fmt::print("dataset {}: {} test cameras, {} submissions\n", dataset.name,
               dataset.info.at("test_images").size(), store.DatasetSubmissions(dataset.id).size());
  }
  for (const auto& participant : store.Participants()) {
    fmt::print("participant {}{}\n", participant.name, participant.revoked ? " (revoked)" : "");
  }
  return static_cast<int>(ExitCode::kOk);
}

CommandRunner SetupBenchmark(CLI::App& app) {
  app.require_subcommand(1);
  auto args = std::make_shared<BenchmarkArguments>();
  CLI::App* add = app.add_subcommand("add-dataset",
                                     "Publish a scene's training photos and test "
                                     "cameras; keep its test photos secret");
  AddRootAndName(add, args.get(), "Dataset name (A-Z a-z 0-9 _ - .)");
  add->add_option("--scene", args->scene, "Scene file or folder (format detected)")->required();
  AddSceneOptions(*add, &args->scene_args);
  add->add_option("--scheme", args->scheme, "every:N | fraction:F[:SEED] | lists:TRAIN,TEST")
      ->required();
  add->add_option("--description", args->description, "One paragraph shown on the pages");
  add->add_option("--shortcut", args->shortcuts,
                  "A file or folder published with the dataset (a mesh, depth maps); repeatable");
  add->add_option("--metrics", args->metrics, "Comma-separated metrics or all")
      ->capture_default_str();
  add->add_option("--headline", args->headline, "The metric that orders the leaderboard")
      ->capture_default_str();
  add->add_option("--window", args->window, "Metric and completeness window (odd)")
      ->capture_default_str();
  add->add_option("--eval-short-side", args->eval_short_side,
                  "Compare at this shorter side in pixels (test cameras scaled, photos "
                  "downscaled; 0 = original)")
      ->capture_default_str();
  add->add_option("--photo-masks", args->photo_masks,
                  "Folder of test-photo masks by stem (0 = ignore the pixel); default: the "
                  "scene's own mask paths, if any");
  add->add_option("--ranking", args->ranking,
                  "How the leaderboard ranks: filled (the headline metric with every pixel not "
                  "rendered counted at its worst value) or min-completeness:F (the headline "
                  "mean among submissions of completeness >= F; the others listed apart)")
      ->capture_default_str();
  add->add_option("--public-fraction", args->public_fraction,
                  "< 1: this random fraction of the test photos ranks the public leaderboard; "
                  "the rest is scored but hidden until 'rephoto benchmark reveal'")
      ->capture_default_str();
  CLI::App* participant =
      app.add_subcommand("add-participant", "Add a participant; prints its API token (last line)");
  AddRootAndName(participant, args.get(), "Participant name");
  CLI::App* revoke = app.add_subcommand("revoke", "Disable a participant's token");
  AddRootAndName(revoke, args.get(), "Participant name");
  CLI::App* reveal = app.add_subcommand(
      "reveal", "Show a dataset's private scores; its leaderboard ranks by the private photos");
  AddRootAndName(reveal, args.get(), "Dataset name");
  CLI::App* list = app.add_subcommand("list", "List datasets and participants");
  list->add_option("--root", args->root, "The benchmark folder")->required();
  return [args, add, participant, revoke, reveal, list]() {
    if (add->parsed()) return RunAddDataset(*args);
    if (list->parsed()) return RunList(*args);
    REPHOTO_CHECK_USAGE(std::filesystem::is_directory(args->root), "--root {}: not a folder",
                        args->root);
    service::Store store(args->root);
    if (reveal->parsed()) {
      service::RevealDataset(store, args->name);
      LogInfo(fmt::format("dataset '{}' revealed", args->name));
      return static_cast<int>(ExitCode::kOk);
    }
    if (revoke->parsed()) {
      store.RevokeParticipant(args->name);
      LogInfo(fmt::format("participant '{}' revoked", args->name));
      return static_cast<int>(ExitCode::kOk);
    }
    REPHOTO_CHECK_USAGE(
        service::IsCleanText(args->name) && !args->name.empty() && args->name.size() <= 100,
        "--name: 1 to 100 bytes of UTF-8 text without control characters");
    const std::string token = store.AddParticipant(args->name);
    fmt::print("participant '{}' added; its API token (shown only now):\n{}\n", args->name, token);
    return static_cast<int>(ExitCode::kOk);
  };
}

}  // namespace

REPHOTO_COMMAND(80, "benchmark", "Administer a benchmark folder (datasets, participants)",
                SetupBenchmark);

}  // namespace rephoto::cli
