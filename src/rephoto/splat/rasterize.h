// CPU forward pass of 3D Gaussian splatting, pixel for pixel the reference CUDA rasterizer
// (graphdeco-inria/diff-gaussian-rasterization, forward.cu) with a full pinhole K.
//
// Per Gaussian (preprocessing): view point p = cam_from_world * mean; culled when p.z <= 0.2.
// Sigma = R S S^T R^T. EWA: cov2D = J W Sigma W^T J^T + 0.3 I (px^2), W = cam_from_world
// rotation, J the perspective Jacobian at p with x/z clamped to [-(cx/fx + 0.3 tx),
// (width - cx)/fx + 0.3 tx], tx = width / (2 fx) (y likewise): the reference's 1.3 tan(half
// fov) clamp, generalised to an off-centre principal point as gsplat does (identical when cx =
// width / 2). Culled when det(cov2D) == 0. Radius = ceil(3 sqrt(max eigenvalue)), eigenvalues
// from mid +- sqrt(max(0.1, mid^2 - det)). Tiles of 16 x 16 pixels: a Gaussian belongs to the
// tiles of the square [centre - radius, centre + radius] exactly as the reference's getRect
// (and is culled when that is empty). Colour = max(SH(dir) + 0.5, 0), dir = unit vector from the
// camera centre to the mean.
// Antialiased mode (gsplat's rasterize_mode="antialiased", Mip-Splatting's 2D filter): opacity
// *= sqrt(max(0, det(cov2D - 0.3 I) / det(cov2D))); everything else as above.
// Per pixel: the one sample is the pixel centre ((x + 0.5, y + 0.5) in rephoto's corner
// convention; the reference's integer pixel coordinates are these minus 0.5, so its mean
// fx * x / z + cx lands on the same pixels). The tile's Gaussians are blended front to back by
// view depth (ties by index, as the reference's stable radix sort): power = -0.5 d^T conic d,
// skipped when > 0; alpha = min(0.99, opacity * exp(power)), skipped when < 1/255; the pixel
// stops before the transmittance T would fall below 1e-4.
// Exactness note: a Gaussian is only blended at pixels where opacity * exp(power) >= 1/255 can
// hold (an ellipse computed per Gaussian); elsewhere the reference skips it too, so results are
// the same; it is only work saved.
//
// Output (GaussianRendering), like every rephoto render (rephoto/render/render.h):
// - color: RGBA float. RGB = the reference image, sum_i c_i alpha_i T_i + T * background
//   (composited over `background`, which is what 3DGS evaluations compare with photos);
//   alpha = 1 - T (coverage; the completeness mask). Where alpha is 0, RGB is the background.
// - depth: 1 channel, expected camera-frame z of the blended Gaussians,
//   sum_i z_i alpha_i T_i / (1 - T); NaN where alpha is 0.
// Distorted cameras (any model but SIMPLE_PINHOLE/PINHOLE): the Gaussians are rasterized on an
// undistorted pinhole grid with the camera's fx, fy covering every pixel's ray (at most 4x the
// image size per axis), then each pixel of the distorted image takes the bilinear RGBA at its
// ray's position on that grid (depth: nearest grid pixel). Pixels whose ray does not exist or
// falls outside the grid are empty (alpha 0, background, NaN depth). Like the reference, the
// rasterizer is a pinhole model; this is the usual approximation (the splat's shape is not
// distorted, only its position and the image around it). The per-pixel undistortion map is
// kept for the last 4 distinct cameras (a process-wide, thread-safe cache of about 8 bytes per
// pixel each), so the views of one camera pay for it once.
//
// Threading and speed: preprocessing, the per-band tile lists and blending (one tile per task)
// run in parallel with ParallelFor (TBB, all cores or a ThreadLimit); the result does not
// depend on the thread count. The blend kernel evaluates, per Gaussian and tile row, the 8 pixels
// around the chord of its alpha >= 1/255 ellipse (both 8-pixel halves when the chord is longer),
// skipping pixels that have stopped, on 8-float vectors (an AVX2 version is chosen at run time
// where the CPU has it, SSE2 otherwise; the same IEEE operations, no FMA) with a polynomial exp
// (relative error < 2e-7 against expf). Memory per view: about 80 bytes per
// visible Gaussian plus 4 bytes per (tile, Gaussian) pair, besides the images. Functions are
// reentrant; the model is only read.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "rephoto/camera/camera.h"
#include "rephoto/core/image.h"
#include "rephoto/splat/gaussians.h"

namespace rephoto::splat {

enum class GaussianMode { kClassic, kAntialiased };

// "classic" or "antialiased"; nullopt otherwise.
std::optional<GaussianMode> ParseGaussianMode(std::string_view text);
// A background colour "R,G,B" (each in [0, 1]), "black" or "white"; throws UsageError
// "<source> <text>: expected R,G,B in [0, 1], black or white" otherwise.
Eigen::Vector3f ParseBackground(std::string_view text, std::string_view source);

struct GaussianRenderOptions {
  GaussianMode mode = GaussianMode::kClassic;
  Eigen::Vector3f background = Eigen::Vector3f::Zero();  // RGB in [0, 1]
};

struct GaussianRendering {
  Image color;  // RGBA, see above
  Image depth;  // 1 channel, expected camera-frame z, NaN = empty
};

// Wall-clock milliseconds per stage of the last render and sizes (for benchmarks and logs).
struct GaussianRenderStats {
  double project_ms = 0;    // preprocessing: cull, covariance, SH colour, tile rectangles
  double sort_ms = 0;       // depth sort and per-tile lists
  double blend_ms = 0;      // per-pixel blending (and resampling for distorted cameras)
  size_t visible = 0;       // Gaussians that survived culling
  size_t tile_entries = 0;  // (tile, Gaussian) pairs blended
};

// Renders `model` at a camera with intrinsics `camera` (image size camera.width x
// camera.height) and pose `cam_from_world`. Throws Error for an invalid camera or a model whose
// arrays disagree in size (values are checked by the readers and GaussianModel::Validate, not
// per render).
GaussianRendering RenderGaussians(const GaussianModel& model, const camera::Camera& camera,
                                  const camera::Pose& cam_from_world,
                                  const GaussianRenderOptions& options = {},
                                  GaussianRenderStats* stats = nullptr);

// The same into `out` (its buffers are reused when they have the right size).
void RenderGaussians(const GaussianModel& model, const camera::Camera& camera,
                     const camera::Pose& cam_from_world, const GaussianRenderOptions& options,
                     GaussianRendering* out, GaussianRenderStats* stats = nullptr);

// Per-Gaussian error accumulation for `rephoto project` on Gaussian models: the blending weight
// of Gaussian i at pixel p is w_i(p) = alpha_i(p) T_i(p) (its contribution to the pixel's
// colour). For a view with a per-pixel error image, weighted_error[i] += sum_p w_i(p) e(p) and
// weight[i] += sum_p w_i(p) over the pixels whose error is finite (NaN = no valid error, e.g.
// outside the photo's mask). The per-Gaussian mean error over many views is then
// weighted_error[i] / weight[i] (undefined where weight is 0: the Gaussian was never seen).
struct GaussianErrorAccumulator {
  std::vector<double> weighted_error;  // one per Gaussian
  std::vector<double> weight;          // one per Gaussian

  void Reset(size_t gaussian_count) {
    weighted_error.assign(gaussian_count, 0.0);
    weight.assign(gaussian_count, 0.0);
  }
};

// Renders the view as RenderGaussians and adds its weights into `accumulator` (resized to the
// model when empty; Error when its size differs). `error` has the camera's size and 1 channel
// (Error otherwise). Distorted cameras: each pixel's error is assigned to the nearest pinhole
// grid pixel (averaged when several fall on one). Deterministic for any thread count.
void AccumulateGaussianErrors(const GaussianModel& model, const camera::Camera& camera,
                              const camera::Pose& cam_from_world,
                              const GaussianRenderOptions& options, const Image& error,
                              GaussianErrorAccumulator* accumulator);

}  // namespace rephoto::splat
