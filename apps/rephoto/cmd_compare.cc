// rephoto compare --photos DIR --renders DIR [--masks DIR] [--photo-masks DIR]
//                 [--metrics a,b,...|all] [--window N] [--ssim-mode gaussian|skimage]
//                 [--dark T] [--saturated T] [--resize] [--no-error-images]
//                 [--images FILE | --split DIR] [--min-alpha A]
//                 [--compat 3dgs|nerfstudio [--compat-background R,G,B]]
//                 [--lpips-weights DIR] [--lpips-net alex|vgg] --out RUN_DIR
// Parses options into compare::CompareOptions and calls compare::RunCompare (see
// src/rephoto/compare/compare.h for inputs, outputs and exit codes).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "command.h"
#include "rephoto/compare/compare.h"
#include "rephoto/compare/compat_compare.h"
#include "rephoto/core/error.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/run/summary_table.h"
#include "rephoto/split/split_writer.h"

namespace rephoto::cli {
namespace {

struct CompareArguments {
  compare::CompareOptions options;
  std::string metrics = "all";
  std::string ssim_mode = "gaussian";
  bool no_error_images = false;
  std::string error_image_metrics = "all";
  bool no_prefetch = false;
  std::string compat;
  std::vector<float> compat_background;
  std::string split;
  std::string lpips_net = "alex";
};

CommandRunner SetupCompare(CLI::App& app) {
  auto args = std::make_shared<CompareArguments>();
  compare::CompareOptions& o = args->options;
  app.add_option("--photos", o.photos, "Folder of photos")
      ->required()
      ->check(CLI::ExistingDirectory);
  app.add_option("--renders", o.renders,
                 "Folder of renderings with the photos' file names (stems); alpha = coverage, "
                 "without alpha pure black = not covered")
      ->required()
      ->check(CLI::ExistingDirectory);
  app.add_option("--masks", o.render_masks,
                 "Folder of rendering masks by name (overrides alpha/black; 0 = not covered)")
      ->check(CLI::ExistingDirectory);
  app.add_option("--photo-masks", o.photo_masks,
                 "Folder of photo masks by name (0 = ignore the photo pixel)")
      ->check(CLI::ExistingDirectory);
  CLI::Option* images =
      app.add_option("--images", o.image_list,
                     "Compare only the images named in this list file (one name per line, as "
                     "a split's test.txt; matched by file name without extension); other photos "
                     "are ignored, not reported missing")
          ->check(CLI::ExistingFile);
  app.add_option("--split", args->split,
                 "Compare only the test images of a `rephoto split` folder: DIR/test.txt of a "
                 "fold folder (DIR/fold_XX), or of the only fold of a single-fold split")
      ->check(CLI::ExistingDirectory)
      ->excludes(images);
  app.add_option("--min-alpha", o.min_alpha,
                 "Coverage of renderings with alpha: a pixel is rendered where alpha >= A "
                 "(`rephoto evaluate` uses 0.5 for Gaussian splatting); 0 = any alpha > 0")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--metrics", args->metrics,
                 "Comma-separated metrics (1-ncc,cb+cr,zssd,dssim,census,icid,psnr,ssim,lpips) "
                 "or all (every metric but lpips, which needs --lpips-weights); with --compat: "
                 "among psnr,ssim,lpips (default: psnr,ssim and lpips when weights are given)")
      ->capture_default_str();
  app.add_option("--lpips-weights", o.lpips_weights,
                 "Folder with the LPIPS weight files under their original names (alex.pth + "
                 "alexnet-owt-7be5be79.pth; vgg.pth + vgg16-397923af.pth) [default: "
                 "$REPHOTO_LPIPS_WEIGHTS]; see docs/lpips.md")
      ->check(CLI::ExistingDirectory);
  app.add_option("--lpips-net", args->lpips_net,
                 "LPIPS network: alex (the lpips package's default) or vgg")
      ->check(CLI::IsMember({"alex", "vgg"}))
      ->capture_default_str();
  app.add_option("--window", o.metric_options.window,
                 "Window side of 1-ncc, zssd, census and completeness (odd)")
      ->check(CLI::Range(3, 101))
      ->capture_default_str();
  app.add_option("--ssim-mode", args->ssim_mode,
                 "SSIM/DSSIM window: gaussian (11x11, sigma 1.5) or skimage (7x7 uniform, "
                 "sample covariance: scikit-image's defaults)")
      ->check(CLI::IsMember({"gaussian", "skimage"}))
      ->capture_default_str();
  app.add_option("--dark", o.exposure.dark_threshold,
                 "Photo pixels with any channel <= this are ill-exposed (negative: off)")
      ->capture_default_str();
  app.add_option("--saturated", o.exposure.saturated_threshold,
                 "Photo pixels with any channel >= this are ill-exposed (> 1: off)")
      ->capture_default_str();
  app.add_flag("--resize", o.resize,
               "Rescale renderings whose size differs to the photo size (area/bilinear)");
  app.add_flag("--no-error-images", args->no_error_images,
               "Do not write errors/<name>.<metric>.exr/.png");
  app.add_option("--error-image-metrics", args->error_image_metrics,
                 "Write error images of these of the --metrics only (comma-separated) or all")
      ->capture_default_str();
  app.add_flag("--no-prefetch", args->no_prefetch,
               "Do not decode the next pair while comparing the current one");
  app.add_option("--compat", args->compat,
                 "Compute psnr and ssim as 3dgs (graphdeco metrics.py: zero-padded SSIM) or "
                 "nerfstudio (ns-eval/torchmetrics) do, for comparison with papers: no masks, "
                 "every pixel; photos with alpha composited over --compat-background")
      ->check(CLI::IsMember({"3dgs", "nerfstudio"}));
  app.add_option("--compat-background", args->compat_background,
                 "Background R,G,B in [0,1] for --compat (the colour the model was trained "
                 "with: 1,1,1 for 3dgs --white_background; default black)")
      ->delimiter(',')
      ->expected(3);
  app.add_option("--out", o.out, "Run folder for per_image.csv, summary.json and errors/")
      ->required();

  return [args] {
    compare::CompareOptions options = args->options;
    options.metrics = metrics::ParseMetricList(args->metrics);
    options.lpips_net = *lpips::ParseLpipsNet(args->lpips_net);
    if (args->ssim_mode == "skimage") {
      options.metric_options.ssim_gaussian = false;
      options.metric_options.ssim_window = 7;
    }
    options.write_error_images = !args->no_error_images;
    if (args->error_image_metrics != "all") {
      try {
        options.error_image_metrics = metrics::ParseMetricList(args->error_image_metrics);
      } catch (const Error& e) {  // it names --metrics
        std::string_view why = e.what();
        if (why.starts_with("--metrics: ")) why.remove_prefix(11);
        throw UsageError(fmt::format("--error-image-metrics: {}", why));
      }
      for (metrics::Metric m : options.error_image_metrics) {
        REPHOTO_CHECK_USAGE(
            std::find(options.metrics.begin(), options.metrics.end(), m) != options.metrics.end(),
            "--error-image-metrics: {} is not among --metrics", metrics::MetricName(m));
      }
    }
    REPHOTO_CHECK_USAGE(args->compat_background.empty() || !args->compat.empty(),
                        "--compat-background needs --compat");
    REPHOTO_CHECK_USAGE(options.min_alpha == 0 || args->compat.empty(),
                        "--min-alpha does not apply with --compat (every pixel is compared)");
    if (!args->split.empty()) options.image_list = split::SplitTestList(args->split);
    if (!args->compat.empty()) {
      options.compat = metrics::ParseCompatPreset(args->compat);
      // The preset's metrics unless --metrics names some (compat_compare.h).
      options.metrics = compare::ResolveCompatMetrics(
          *options.compat,
          args->metrics == "all" ? std::vector<metrics::Metric>{} : options.metrics,
          options.lpips_weights);
      if (!args->compat_background.empty()) {
        options.compat_background = {args->compat_background[0], args->compat_background[1],
                                     args->compat_background[2]};
      }
      options.write_error_images = false;  // no error images in compat mode
    }
    options.prefetch = !args->no_prefetch;
    const compare::CompareResult result = compare::RunCompare(options);

    fmt::print("{} pairs compared, {} without counterpart\n", result.images.size(),
               result.missing.size());
    std::vector<run::SummaryRow> rows = {{"completeness", result.completeness, 0, false}};
    for (const compare::MetricSummary& m : result.metrics) {
      rows.push_back({std::string(metrics::MetricName(m.metric)), m.over_images, m.pooled});
    }
    fmt::print("{}", run::FormatSummaryTable("over images", "mean", rows));
    for (const compare::MissingImage& missing : result.missing) {
      fmt::print("missing {} for {}\n",
                 missing.missing == compare::Missing::kRender ? "rendering" : "photo",
                 missing.present.string());
    }
    fmt::print("Results in {} (summary.json, per_image.csv{})\n", options.out.string(),
               options.write_error_images ? ", errors/" : "");
    return static_cast<int>(result.exit_code());
  };
}

REPHOTO_COMMAND(20, "compare",
                "Compare photos with renderings of the same views (paired by file name): "
                "per-image and overall errors, completeness, error images",
                SetupCompare);

}  // namespace
}  // namespace rephoto::cli
