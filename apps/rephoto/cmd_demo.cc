// rephoto demo [--out DIR] [--cameras N] [--width W --height H]
#include <fmt/format.h>

#include <memory>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/demo/demo.h"

namespace rephoto::cli {
namespace {

CommandRunner SetupDemo(CLI::App& app) {
  auto options = std::make_shared<demo::DemoOptions>();
  options->out = "rephoto-demo";
  app.add_option("--out", options->out, "Output folder")->capture_default_str();
  app.add_option("--cameras", options->scene.camera_count, "Cameras on the ring")
      ->check(CLI::Range(3, 360))
      ->capture_default_str();
  app.add_option("--width", options->scene.image_width, "Photo width in pixels")
      ->check(CLI::Range(64, 8192))
      ->capture_default_str();
  app.add_option("--height", options->scene.image_height, "Photo height in pixels")
      ->check(CLI::Range(48, 8192))
      ->capture_default_str();
  app.add_option("--seed", options->scene.seed, "Seed of the procedural scene")
      ->capture_default_str();
  app.add_option("--suggestions", options->suggestions,
                 "Views the acquisition step suggests for the photos of one side (0: skip it)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  return [options] {
    const demo::DemoResult result = demo::RunDemo(*options);
    fmt::print(
        "Reconstructions of the demo scene, ranked by median 1-NCC across {} folds ({} photos)\n",
        result.ranking.empty() ? 0 : result.ranking.front().result.folds.size(),
        options->scene.camera_count);
    fmt::print("{:<4} {:<16} {:>12} {:>8} {:>8} {:>8}  {}\n", "rank", "reconstruction",
               "completeness", "1-ncc", "cb+cr", "dssim", "what");
    int rank = 1;
    for (const auto& r : result.ranking) {
      fmt::print("{:<4} {:<16} {:>12.4f} {:>8.4f} {:>8.4f} {:>8.4f}  {}\n", rank++, r.name,
                 r.result.completeness_across_folds.median, r.Median(metrics::Metric::kOneMinusNcc),
                 r.Median(metrics::Metric::kCbCr), r.Median(metrics::Metric::kDssim),
                 r.description);
    }
    if (result.suggestions) {
      const demo::DemoSuggestions& next = *result.suggestions;
      fmt::print(
          "Where to photograph next: with only the {} photos from one side, {:.1f} % of the "
          "surface is seen by no photo; the {} suggested views see {:.1f} % of it (in {})\n",
          next.photos_so_far, 100 * next.unseen_fraction, options->suggestions,
          100 * next.covered_fraction, next.folder.string());
    }
    fmt::print(
        "Done in {:.0f} s. Open {} in a browser; tables in ranking.csv and runs/<name>/, "
        "error on the models in runs/<name>/projected/1-ncc.ply\n",
        result.seconds, (options->out / "report.html").string());
    return static_cast<int>(ExitCode::kOk);
  };
}

REPHOTO_COMMAND(90, "demo",
                "Run the built-in example: photograph a procedural scene, evaluate six "
                "reconstructions of it, rank them and suggest where to photograph next",
                SetupDemo);

}  // namespace
}  // namespace rephoto::cli
