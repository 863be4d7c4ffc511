// Rephotographing a model: ray-cast rendering at a photo's exact camera (intrinsics,
// distortion, pose, resolution) with Embree.
//
// Sampling: each pixel (x, y) covers [x, x+1) x [y, y+1) (pixel-corner convention, as
// camera.h). With samples_per_pixel = 1 the single sample is the pixel centre (x + 0.5,
// y + 0.5). With n > 1 samples the pixel is split into kx x ky strata, kx = ceil(sqrt(n)),
// ky = ceil(n / kx), filled row by row; sample s lies in stratum (s % kx, s / kx), at the stratum
// centre (SamplePattern::kRegular) or at a uniformly jittered position inside it
// (kStratifiedJittered; the jitter is a hash of pixel, sample and `seed`: deterministic).
// Each sample's ray comes from unprojecting its position with the camera's own model
// (CameraRays). Samples are box-filtered.
//
// Output (Rephoto):
// - color: RGBA float, 4 channels. RGB = mean colour of the samples that hit the model
//   (straight, not premultiplied, alpha; 0 where nothing was hit), values as the model stores
//   them; alpha = fraction of the pixel's samples that hit the model (the coverage /
//   completeness mask, in [0,1]).
// - depth: 1 channel, the camera-frame z (not the ray length) of the nearest hit among the
//   pixel's samples, in model units; NaN where no sample hit.
// Rays start at the camera centre (t = 0) and are unbounded.
// Hits (docs/determinism.md): Embree finds the candidate triangles; of those, the one with the
// smallest (t, triangle index) by rephoto's own Moeller-Trumbore in float (fixed operation
// order) is the hit, and its t, u, v are those values, so a render is the same bytes on every
// CPU and instruction-set path (core/isa.h) and with either packet width, also where surfaces
// overlap within rounding. Point discs: rephoto's own disc test, the lowest index among discs at
// exactly the same distance.
// Backfaces: a triangle's front side is the side its normal (p1 - p0) x (p2 - p0) points to.
// With backfaces = false, hits on a triangle's back side are ignored (the ray continues).
// Performance: packets of 8 or 16 coherent rays (RenderOptions::packet_width: 16 where Embree
// traces 16 natively, i.e. AVX-512) over tiles of 4 x 2 or 4 x 4 pixels (one sample each, or
// the samples of 2 x 2 pixels), tile rows in parallel (ParallelFor); ray setup, vertex-colour
// shading and the tile's output in vectorized lane loops, compiled for AVX-512, AVX2 and the
// baseline (same results bit for bit); no allocation per pixel. The price of deciding hits
// itself (nearest_hit.h: a filter call per candidate hit, robust traversal, border strips): at
// 1920x1080, 1 sample per pixel, 1M triangles, 2 threads the CPU time is 1.45x that of
// Embree's rtcIntersect16 alone on the same rays on the AVX-512 path, 1.21x of rtcIntersect8 on
// AVX2 (1.59x and 1.35x before the filter was vectorized; 0.92x and 1.02x when Embree's rounding
// decided; bench/bench_render.cc, BM_RenderOverFloor).
//
// Thread safety: RenderRephoto only reads the RenderModel and CameraRays (Embree queries on a
// committed scene are thread-safe), so several threads may render one model at once, each into its
// own Rephoto; it also parallelizes inside (core/parallel.h).
#pragma once

#include <cstdint>

#include "rephoto/camera/camera.h"
#include "rephoto/core/image.h"
#include "rephoto/render/camera_rays.h"
#include "rephoto/render/render_model.h"

namespace rephoto::render {

enum class SamplePattern { kStratifiedJittered, kRegular };

struct RenderOptions {
  int samples_per_pixel = 4;  // >= 1
  SamplePattern pattern = SamplePattern::kStratifiedJittered;
  uint32_t seed = 0;
  bool backfaces = true;  // render the back sides of triangles
  // Rays per Embree packet, 8 or 16; 0: by CPU (16 where Embree has native 16-ray packets, i.e.
  // AVX-512, else 8). The image is the same either way (each ray's hit, then each pixel's
  // samples summed in increasing order).
  int packet_width = 0;
};

struct Rephoto {
  Image color;  // RGBA, see above
  Image depth;  // 1 channel, camera-frame z, NaN = empty
};

// Renders `model` seen by a camera with intrinsics `camera` (image size = camera.width x
// camera.height) at pose `cam_from_world`. Uses model.RaysFor(camera). Throws Error for an
// invalid camera (e.g. zero focal length) or samples_per_pixel < 1.
Rephoto RenderRephoto(const RenderModel& model, const camera::Camera& camera,
                      const camera::Pose& cam_from_world, const RenderOptions& options = {});

// The same with an explicit ray table, writing into `out` (its buffers are reused when they
// already have the right size: render many views without reallocating).
void RenderRephoto(const RenderModel& model, const CameraRays& rays,
                   const camera::Pose& cam_from_world, const RenderOptions& options, Rephoto* out);

// Position (in [0,1)^2 inside the pixel) of sample `sample` of pixel (x, y); see above.
Eigen::Vector2f SampleOffset(int x, int y, int sample, const RenderOptions& options);

}  // namespace rephoto::render
