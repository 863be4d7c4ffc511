// `rephoto compare`: photos against renderings of the same views, by file stem.
//
// Inputs
//   photos/       the photos (PNG, JPEG, EXR, PFM; see io/image_io.h).
//   renders/      renderings with the same stems. Alpha (2 or 4 channels) is the completeness
//                 mask: by default any alpha > 0 is covered; with min_alpha > 0 a pixel is
//                 covered where its alpha reaches min_alpha (alpha >= min_alpha, alpha as a
//                 value in [0, 1]: 8-bit v stands for v / 255), the rule `rephoto evaluate`
//                 applies to Gaussian splatting renderings (0.5 there: a splat's soft edge covers
//                 a pixel only partly), so a rendering from any renderer can be held to it.
//                 Without alpha, pure black pixels (all channels exactly 0) are not covered, as
//                 the paper's benchmark does; min_alpha does not apply to them.
//   render_masks/ optional, by stem: overrides alpha/black; valid where the first channel > 0.
//                 Must hold a mask for every compared pair, at the rendering's size.
//   photo_masks/  optional, by stem: user masks of the photos (first channel 0 = ignore the
//                 pixel, e.g. sky, moving people). Must hold a mask for every compared pair, at
//                 the photo's size. A photo's own alpha channel, if any, acts the same way.
//   Photo pixels that are ill-exposed (any colour channel <= dark or >= saturated threshold)
//   are invalid too (metrics/validity.h). Grey images are replicated to RGB.
//   Renderings whose size differs from their photo are an error naming both files and sizes,
//   unless `resize`: then the rendering (and its mask) is rescaled to the photo's size, see
//   resample.h; validity (alpha/black/mask) is decided before rescaling.
//
// Selection: with `image_list` (a list file as split::ReadImageList reads it, e.g. a split's
// fold_XX/test.txt) only the listed images are compared. Each name must pass
// scene::CheckedImageName (no "..", no absolute path, ...; else an Error "<list>:<line>: image
// name ..."); it stands for the stem of its file name (the name's last component without its
// image extension: "images/IMG_1.JPG" -> "IMG_1"; a name without one is the stem itself). Two
// names with one stem are an Error naming both lines, as is a name with neither a photo nor a
// rendering (a list of another scene). Unlisted photos and renderings are ignored (neither
// compared nor missing, and not in the counts); a listed name with only one of the two is
// missing as below.
//
// Pairing: see pairing.h. A photo without a rendering or a rendering without a photo is a
// warning line, a row of per_image.csv and an entry of summary.json "missing"; the run then
// finishes with ExitCode::kIncomplete. No pair at all, or an empty folder, is an Error.
// All pairs' file headers (sizes) and the presence of all masks are checked before any pixel
// is compared, so such mistakes fail in seconds, not after hours.
//
// Outputs in `out` (the run directory):
//   per_image.csv  one row per image name, sorted by name. Columns: name, status ("ok",
//                  "missing_render", "missing_photo"), photo, render (paths), width, height
//                  (compared size = photo size), resized (0/1), completeness,
//                  valid_photo_windows, valid_both_windows, then for each metric "<metric>" (the
//                  image's mean, empty when nothing was evaluated) and "<metric>_evaluated"
//                  (positions in that mean). Missing rows leave the measurements empty.
//   summary.json   schema "rephoto.compare/1": tool version, parameters, counts, completeness
//                  and each metric summarised over images (mean, min, q1, median, q3, max of the
//                  per-image values, NaN-free; "images" = how many had a value) plus
//                  "pooled" (all evaluated positions of all images together; for psnr the PSNR
//                  of the pooled MSE), the colour range of its error PNGs, and the "missing" list.
//   errors/<name>.<metric>.exr  the per-pixel error image (1 channel float, NaN = not evaluated)
//   errors/<name>.<metric>.png  the same, jet-coloured over a fixed range per metric
//                  (ErrorColourRange), transparent where not evaluated.
// Every file is written atomically. The whole run is staged in a hidden folder inside `out`
// and moved into place only when everything succeeded (summary.json last), so a failed or
// interrupted run leaves the previous results of `out` untouched. A rerun recomputes
// everything and replaces per_image.csv, summary.json and the whole errors/ folder.
//
// Memory: one pair at a time (plus the next pair being decoded while the current one is
// compared); all large buffers are reused between pairs. 8-bit files (JPEG, 8-bit PNG) stay
// 8-bit in memory (the metrics convert rows band by band), RGBA renderings are not copied to
// RGB, and no whole error image is held: the metrics run in bands of rows whose error rows go
// straight into the EXR files, and each PNG is made afterwards from its EXR's rows, one at a
// time. Peak RSS on one 4000x3000 JPEG/RGBA-PNG pair: ~34 bytes per pixel with all metrics and
// error images (mostly the PNG encoder's buffers), ~15 without error images; with several
// pairs the next pair decoded meanwhile adds ~9 (42 with all metrics and error images).
//
// The files it writes, their columns and units: docs/run-folder.md.
#pragma once

#include <array>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "rephoto/compare/pairing.h"
#include "rephoto/core/error.h"
#include "rephoto/core/image.h"
#include "rephoto/core/stats.h"
#include "rephoto/lpips/lpips.h"
#include "rephoto/metrics/compat.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/metrics/validity.h"

namespace rephoto::compare {

struct CompareOptions {
  std::filesystem::path photos;
  std::filesystem::path renders;
  std::filesystem::path render_masks;  // empty = use alpha / black
  std::filesystem::path photo_masks;   // empty = none
  std::filesystem::path out;
  // Compare only the images this list file names (see "Selection" above); empty = all.
  std::filesystem::path image_list;
  // Coverage rule for renderings with alpha (see "Inputs" above): 0 = alpha > 0, else alpha >=
  // min_alpha; in [0, 1]. Not with compat (no masks there). Also applies to
  // ComparePhotoAndRender / CompareInMemory; an explicit rendering mask overrides it.
  double min_alpha = 0;
  std::vector<metrics::Metric> metrics = metrics::AllMetrics();
  metrics::MetricOptions metric_options;  // window (also the completeness window), SSIM mode...
  metrics::ExposureOptions exposure;      // photo dark/saturated thresholds
  bool resize = false;                    // rescale renderings to their photo's size
  bool write_error_images = true;         // errors/*.exr and *.png
  // Of `metrics`, those whose error images are written (empty = all). Each is 4 bytes per pixel
  // as EXR plus its PNG: at 12 MP, 8 metrics write about 0.5 GB per image.
  std::vector<metrics::Metric> error_image_metrics;
  bool prefetch = true;  // decode the next pair while comparing the current
  // --compat: compare as graphdeco's metrics.py or nerfstudio's ns-eval do (compat_compare.h:
  // no masks, psnr and ssim only, no error images); photos with alpha are composited over
  // compat_background (RGB in [0,1]).
  std::optional<metrics::CompatPreset> compat;
  std::array<float, 3> compat_background = {0, 0, 0};
  // lpips (when `metrics` holds it; lpips/lpips.h, docs/lpips.md): the directory with the
  // weight files under their original names (empty = $REPHOTO_LPIPS_WEIGHTS) and the network
  // (AlexNet, the lpips package's default, or VGG16). Without compat, the lpips value of an
  // image is the mean of the LPIPS spatial map over the joint validity mask ("lpips_evaluated"
  // = its pixels) and its error image is that map (NaN where not valid); with compat it is the
  // whole-image value the lpips package returns, as papers print it (evaluated = all pixels).
  // The network sees the whole photo and rendering (alpha dropped, grey replicated), whatever
  // the masks. The model is loaded once per process (LpipsModel::LoadShared) and shared
  // read-only by every pair and thread; Check() loads it, so missing weights fail before any
  // pair is read (UsageError saying which files and how to get them).
  std::filesystem::path lpips_weights;
  lpips::LpipsNet lpips_net = lpips::LpipsNet::kAlex;

  // Throws Error on invalid settings (missing folders are reported by RunCompare).
  void Check() const;
};

struct MetricValue {
  double mean = 0;       // the image's masked mean (see metrics.h); NaN if nothing evaluated
  size_t evaluated = 0;  // positions in that mean
};

struct ImageResult {
  std::string name;
  std::filesystem::path photo;
  std::filesystem::path render;
  int width = 0;  // compared size (the photo's)
  int height = 0;
  bool resized = false;  // the rendering was rescaled
  metrics::Completeness completeness;
  std::vector<MetricValue> metrics;  // in CompareOptions::metrics order
};

struct MetricSummary {
  metrics::Metric metric = metrics::Metric::kOneMinusNcc;
  Summary over_images;   // of the per-image means (NaN means skipped)
  double pooled = 0;     // over all evaluated positions of all images (psnr: of pooled MSE)
  size_t evaluated = 0;  // total positions
};

struct CompareResult {
  std::vector<ImageResult> images;     // sorted by name
  std::vector<MissingImage> missing;   // sorted by name
  std::vector<MetricSummary> metrics;  // in CompareOptions::metrics order
  Summary completeness;                // over images
  size_t photo_count = 0;              // photos (with image_list: the listed ones found)
  size_t render_count = 0;             // renderings (with image_list: the listed ones found)

  // kOk, or kIncomplete when some image had no counterpart.
  ExitCode exit_code() const { return missing.empty() ? ExitCode::kOk : ExitCode::kIncomplete; }
};

// Runs the comparison and writes the outputs (see above). Throws Error (naming the file and
// the problem) on bad input; nothing of a failed run is left in `out`.
CompareResult RunCompare(const CompareOptions& options);

// ------------------------------------------------------------------------------------------
// Building blocks for callers that pair photos and renderings themselves (`rephoto evaluate`):
// the same per-pair comparison, per_image.csv row and summaries RunCompare uses.

// Buffers reused from pair to pair (not thread-safe: one per concurrent caller).
class CompareWorkspace {
 public:
  CompareWorkspace();
  ~CompareWorkspace();
  CompareWorkspace(const CompareWorkspace&) = delete;
  CompareWorkspace& operator=(const CompareWorkspace&) = delete;
  struct Buffers;
  std::unique_ptr<Buffers> buffers;
};

// Compares one decoded pair exactly as RunCompare does (validity from the photo's alpha,
// `photo_mask`, exposure; the rendering's alpha (options.min_alpha)/black or `render_mask`;
// rescaling when
// options.resize and the sizes differ, else sizes must match). `photo_path` and `render_path`
// are only recorded in the result. When options.write_error_images, writes
// <error_folder>/<name>.<metric>.exr and .png (`name` may contain '/': the subfolders must
// exist) while it compares. When `error_images` is not null, nothing is written: it receives
// the error images instead, as CompareInMemory gives them, for a caller that writes them later
// (WriteErrorImages in error_images.h writes the same files). Masks may be null. Throws Error
// naming the files on a size mismatch. `photo` and `render` are Image or Image8 (as for
// CompareInMemory below: an 8-bit image gives the same values as its floats v / 255.f, bit for
// bit, and skips their conversion).
template <typename P, typename R>
ImageResult ComparePhotoAndRender(
    const CompareOptions& options, const std::string& name, const std::filesystem::path& photo_path,
    const std::filesystem::path& render_path, const ImageT<P>& photo, const ImageT<R>& render,
    const Mask* photo_mask, const Mask* render_mask, const std::filesystem::path& error_folder,
    CompareWorkspace* workspace, std::vector<Image>* error_images = nullptr);

// One pair compared in memory (the Python package, rephoto.compare): the same function as
// ComparePhotoAndRender underneath, so the same validity, resizing, compat and values, bit for
// bit, without file paths. `photo` and `render` are Image (floats in [0,1]) or Image8 (8-bit
// samples, v standing for v / 255 as io::ReadImage8 gives them; instantiated for float and
// uint8_t), 1 to 4 channels, as a decoder returns them; messages name them "photo" and
// "render". options.write_error_images and the folders of `options` are ignored, nothing is
// written. When `error_images` is not null it receives one whole width x height x 1 error image
// per metric of options.metrics, in that order (NaN = not evaluated; under options.compat the
// squared error for psnr and the SSIM map for ssim). Throws UsageError on an empty or repeated
// metric list or masks under compat, Error as ComparePhotoAndRender. `workspace`: one per
// concurrent caller.
template <typename P, typename R>
ImageResult CompareInMemory(const CompareOptions& options, const ImageT<P>& photo,
                            const ImageT<R>& render, const Mask* photo_mask,
                            const Mask* render_mask, std::vector<Image>* error_images,
                            CompareWorkspace* workspace);

// per_image.csv columns (see above) for these metrics, and one "ok" row of an image.
std::vector<std::string> PerImageCsvHeader(const std::vector<metrics::Metric>& metrics);
std::vector<std::string> PerImageCsvRow(const ImageResult& image);

// Per-metric summaries over `images` (each ImageResult::metrics in `metrics` order): the
// over-images summary of the per-image means and the pooled value, as in summary.json.
std::vector<MetricSummary> SummarizeMetrics(const std::vector<metrics::Metric>& metrics,
                                            const std::vector<ImageResult>& images);

// Fixed colour range [low, high] of a metric's jet PNGs, the same for every image so that
// images can be compared by eye. low maps to dark blue, high (and beyond) to dark red; for
// ssim low > high (1 = identical is blue). The upper end is the value of unrelated content
// where there is one (1-ncc 1, dssim 0.5, census 0.5, ssim 0), else a typical large error:
//   1-ncc [0, 1]   cb+cr [0, 0.25]   zssd [0, 0.05]   dssim [0, 0.5]   census [0, 0.5]
//   icid [0, 0.5]  psnr (squared error) [0, 0.0625]   ssim [1, 0]   lpips (spatial map) [0, 0.5]
std::pair<float, float> ErrorColourRange(metrics::Metric metric);

// Colours a 1-channel error image with JetColor over [low, high] (low > high reverses) into
// 8-bit RGBA, alpha 0 where the value is NaN. `rgba` is resized to width*height*4.
void ColourErrorImage(const Image& error, float low, float high, std::vector<uint8_t>* rgba);

// Whether the error images of `metric` are written under `options` (write_error_images, and
// error_image_metrics empty or holding it).
bool WritesErrorImage(const CompareOptions& options, metrics::Metric metric);

// The tool version written into summary.json.
std::string ToolVersion();

// The LPIPS model `options` name (lpips_weights or $REPHOTO_LPIPS_WEIGHTS, lpips_net), loaded
// once per process. Throws UsageError (lpips::MissingWeightsMessage) when the files are
// missing, Error when they are not valid. Thread-safe.
std::shared_ptr<const lpips::LpipsModel> LpipsModelFor(const CompareOptions& options);

}  // namespace rephoto::compare
