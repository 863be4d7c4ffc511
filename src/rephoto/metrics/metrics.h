// Image-difference metrics of virtual rephotography (SPEC "Metrics", paper Section 3.2).
//
// Inputs are a photo and a rephoto of the same size, 3 channels (RGB, interleaved, values as
// stored in the files scaled to [0,1]), and a per-pixel validity mask that is the AND of the
// photo's and the rephoto's validity (see validity.h). Every metric yields
//   - an error image: 1 channel, same size, one value per pixel; for window metrics the value
//     at (x, y) belongs to the window centred on pixel (x, y). NaN where the metric is not
//     evaluated: a window metric only where every pixel of the window is valid (windows that
//     leave the image are never evaluated), a pixel metric only at valid pixels;
//   - a masked mean over exactly the evaluated positions (denominator = their count).
//
// Metric              error image value                    mean                     range
// 1-ncc               1 - NCC of the window (RGB jointly)  mean                     [0, 2]
// cb+cr               |dCb| + |dCr|, BT.601 full range     mean                     [0, 2]
// zssd                sum((x-mx)-(y-my))^2 / window pixels, per channel, averaged     [0, 4]
// dssim               (1 - SSIM) / 2, per channel averaged mean                     [0, 1]
// census              Hamming distance / (window px - 1)   mean                     [0, 1]
// icid                iCID difference (Preiss et al. 2014) mean                     [0, 1]
// psnr                squared error, averaged over channels  10 log10(1 / masked MSE) dB
// ssim                SSIM, per channel averaged            mean SSIM                [-1, 1]
// lpips               LPIPS spatial map (network metric)    see below                [0, ~1]
//
// lpips is not computed here: it is a whole-image network (Zhang et al. 2018, src/rephoto/lpips,
// docs/lpips.md) that needs weight files, computed per pair by compare (CompareOptions), which
// reports the spatial map's mean over the completeness mask (or, under --compat, the
// whole-image value papers print). It is in the registry (name, parsing, direction) but not in
// AllMetrics() nor "all" (which need no weights); ComputeMetrics* throw for it.
//
// psnr's mean is in dB and +infinity when the masked MSE is 0; its error image holds the
// per-pixel squared error averaged over the three channels. iCID: see icid.h for the colour
// space and which optional steps of Preiss et al. are (not) implemented.
//
// Implementation and accuracy. 1-ncc and zssd of 8-bit values (8-bit inputs, and float inputs
// whose every value in a band's rows is k / 255.f, as io::ReadImage makes them) with windows up
// to 9 x 9 use exact window sums of the integers k (int32 column sums sliding down the image,
// added along rows), so only the final formula rounds (in double); other inputs use window sums
// in double (column sums, prefix sums along rows), so E[x^2] - E[x]^2 keeps ~12 significant
// digits. Both give the same float error values but for last-bit roundings (~1e-12 apart before
// the rounding to float), and an 8-bit image and its float conversion give identical results;
// census compares luma in fixed point (kernels.h CensusKey: 63750 steps over [0, 1], for 8-bit
// colours exactly (299 R + 587 G + 114 B) >> 2, the same for an 8-bit image and its floats); ssim/dssim filter in float (separable, values shifted by
// -0.5 to reduce cancellation): per-pixel values agree with a double-precision reference to
// ~2e-5 and the means with scikit-image to ~1e-6 (tests). Costs do not depend on the window
// size except for the exact path's sums along rows (window adds) and the separable Gaussian (2 x
// window taps). Work is split over bands of 32 image
// rows (ParallelFor), each band going through all requested metrics while its rows are in
// cache (8-bit inputs are converted to floats there, once per band); partial sums are added in
// band order, so results do not depend on the thread count nor on whether the error images are
// whole (ComputeMetrics) or handed over in bands (ComputeMetricsInBands). iCID's Lab
// conversion uses a table for 8-bit values and glibc's cube root written out (icid.cc), both
// bit-identical to the library calls they replace. Row kernels have AVX-512 / AVX2 / baseline variants picked at run time; they
// agree bit for bit except the SSIM filters, which use FMA where available (last-bit
// differences between CPUs). Identical images give exactly 0 (ssim exactly 1, psnr +inf).
// Pixels with a non-finite value (NaN, infinity) in either image are treated as invalid.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/core/image.h"

namespace rephoto::metrics {

enum class Metric { kOneMinusNcc, kCbCr, kZssd, kDssim, kCensus, kIcid, kPsnr, kSsim, kLpips };

// Names as used on the command line and in outputs: "1-ncc", "cb+cr", "zssd", "dssim",
// "census", "icid", "psnr", "ssim", "lpips".
std::string_view MetricName(Metric metric);
// Parses a name (case-insensitive); std::nullopt if unknown.
std::optional<Metric> ParseMetric(std::string_view name);
// Parses a comma-separated list ("1-ncc,psnr" or "all"); throws Error naming an unknown entry.
std::vector<Metric> ParseMetricList(std::string_view list);
// All band metrics (every metric but lpips) in the order of the table above: what "all" means.
const std::vector<Metric>& AllMetrics();
// True for lpips, the one metric computed by a network outside ComputeMetrics (see above).
bool IsNetworkMetric(Metric metric);

// The metric a run is summed up by (the paper's headline, Section 4: 1-NCC) when `metrics`
// holds it, else the first of `metrics`. Throws Error for an empty list.
Metric HeadlineMetric(const std::vector<Metric>& metrics);
// True when a larger value is better (psnr, ssim); false for errors. The one definition: the
// tables, reports and rankings all ask this.
bool HigherIsBetter(Metric metric);
// True when a larger value of the metric's per-pixel error image is better: ssim's holds the
// similarity; psnr's holds the squared error (lower is better) although psnr itself is higher
// is better; every other metric's holds its error.
bool ErrorImageHigherIsBetter(Metric metric);

struct MetricOptions {
  // Window side for 1-ncc, zssd and census (odd, >= 3).
  int window = 9;
  // SSIM/DSSIM window. Gaussian mode (default): 11x11 window, sigma 1.5, population
  // covariance (Wang et al. 2004; scikit-image gaussian_weights=True, sigma=1.5,
  // use_sample_covariance=False). Uniform mode: ssim_window x ssim_window box (set
  // ssim_window = 7 for scikit-image's defaults) with sample covariance (N/(N-1)). Gaussian
  // weights are exp(-k^2 / (2 sigma^2)) for |k| <= ssim_window / 2, normalised, as scipy's
  // gaussian_filter (truncate 3.5) uses for sigma 1.5. Computed in float32 (moments of the
  // values minus a per-strip mean, so nearly flat windows keep their precision): the mean
  // agrees with scikit-image's float64 to ~2e-7 or better (Gaussian mode; tests in
  // metrics_skimage_test.cc and ssim_kernel_test.cc).
  bool ssim_gaussian = true;
  int ssim_window = 11;
  double ssim_sigma = 1.5;
  // 1-NCC flat-patch rule: a window whose summed squared deviation from its per-channel means
  // (over its pixels and channels, values in [0,1]) is at or below this value is flat. Both
  // flat: error 0; one flat: error 1. 1e-6 over 9x9x3 values is an RMS deviation of ~6e-5, far
  // below one 8-bit step (1/255), so only truly constant (or 16-bit near-constant) patches are
  // flat.
  double ncc_flat_threshold = 1e-6;
  // iCID Gaussian: 11x11, sigma 2 (Preiss et al. 2014).
  int icid_window = 11;
  double icid_sigma = 2.0;
};

struct MetricResult {
  Metric metric = Metric::kOneMinusNcc;
  Image error;           // 1 channel; NaN where not evaluated
  double mean = 0;       // see table; NaN when nothing was evaluated
  size_t evaluated = 0;  // number of positions that entered the mean
};

// Computes `metrics` for one photo/rephoto pair. `valid` is the joint per-pixel validity
// (same size; empty = all valid). Throws Error if sizes or channel counts (must be 3) differ.
// Metrics share intermediate sums, so asking for several at once is cheaper than one by one.
std::vector<MetricResult> ComputeMetrics(const Image& photo, const Image& rephoto,
                                         const Mask& valid, const std::vector<Metric>& metrics,
                                         const MetricOptions& options = {});

// Same, writing into `results` (resized to metrics.size(), in that order) and reusing the
// allocations of the error images already there: pass the same vector for successive pairs to
// avoid the cost of touching fresh memory (about 10 us per 4 KiB page on the target machines).
void ComputeMetrics(const Image& photo, const Image& rephoto, const Mask& valid,
                    const std::vector<Metric>& metrics, const MetricOptions& options,
                    std::vector<MetricResult>* results);

// Read-only view of the colour of an image for ComputeMetricsInBands: 3 (RGB) or 4 (RGBA, the
// alpha is ignored) channels, either floats in [0,1] (Image) or 8-bit samples as stored in a
// file (Image8; the sample v stands for static_cast<float>(v) / 255.f, exactly the float that
// io::ReadImage returns for it, so both give bit-identical results). The image must outlive
// the view.
class RgbView {
 public:
  RgbView(const Image& image)  // NOLINT(google-explicit-constructor): a view of the image
      : floats_(image.data()),
        width_(image.width()),
        height_(image.height()),
        channels_(image.channels()) {}
  RgbView(const Image8& image)  // NOLINT(google-explicit-constructor)
      : bytes_(image.data()),
        width_(image.width()),
        height_(image.height()),
        channels_(image.channels()) {}
  int width() const { return width_; }
  int height() const { return height_; }
  int channels() const { return channels_; }
  const float* floats() const { return floats_; }  // null for an 8-bit image
  const uint8_t* bytes() const { return bytes_; }  // null for a float image

 private:
  const float* floats_ = nullptr;
  const uint8_t* bytes_ = nullptr;
  int width_ = 0, height_ = 0, channels_ = 0;
};

// Receives the error rows [y0, y1) of every requested metric: errors[i] holds (y1 - y0) rows
// of width floats of metrics[i]'s error image (valid only during the call). Called on the
// calling thread, for consecutive bands from the top row to the bottom one.
using ErrorBandSink = std::function<void(int y0, int y1, std::span<const float* const> errors)>;

// ComputeMetrics without whole error images: the rows of the error images are handed to `sink`
// band by band (a few hundred rows at a time) as they are made, and the error images of
// `results` are left empty; means and counts are bit-identical to ComputeMetrics'. Working
// memory is a few bands of rows, independent of the image height. An empty `sink` (nullptr)
// computes only the means and counts (error rows stay in per-thread scratch, in cache). Inputs may be float or 8-bit,
// RGB or RGBA (see RgbView); `valid` as for ComputeMetrics. Non-finite input values: as
// ComputeMetrics (invalid pixels), at the cost of a copy of the float inputs that have any.
void ComputeMetricsInBands(const RgbView& photo, const RgbView& rephoto, const Mask& valid,
                           const std::vector<Metric>& metrics, const MetricOptions& options,
                           const ErrorBandSink& sink, std::vector<MetricResult>* results);

// One metric (convenience wrapper of ComputeMetrics).
MetricResult ComputeMetric(Metric metric, const Image& photo, const Image& rephoto,
                           const Mask& valid, const MetricOptions& options = {});

}  // namespace rephoto::metrics
