// LPIPS, the Learned Perceptual Image Patch Similarity of Zhang et al. 2018 ("The Unreasonable
// Effectiveness of Deep Features as a Perceptual Metric"), computed exactly as the `lpips`
// package's version 0.1 "net-lin" model does: lpips.LPIPS(net='alex'|'vgg', version='0.1')
// called with normalize=True on images in [0, 1]. docs/lpips.md has the details and the
// measurements behind the choices below.
//
// Forward pass (per image x, RGB in [0, 1], any size the network accepts):
//   x' = 2x - 1; ScalingLayer: (x' - shift) / scale, shift = (-.030, -.088, -.188),
//   scale = (.458, .448, .450); the torchvision AlexNet (default) or VGG16 "features" up to the
//   five ReLU outputs the package taps (alex: relu1..relu5; vgg: relu1_2, 2_2, 3_3, 4_3, 5_3).
//   For each tapped layer l with features f0, f1 (C_l channels, h_l x w_l):
//   n = f / (sqrt(sum_c f^2) + 1e-10) per pixel; d_l = sum_c w_lc (n0_c - n1_c)^2 (the 1x1
//   "lin" layer, no bias, non-negative weights in the released files).
//   Whole-image value (what papers print): sum_l mean over the h_l x w_l positions of d_l.
//   Spatial map (lpips spatial=True): sum_l of d_l upsampled bilinearly (align_corners=False)
//   to the input size. Masked value (rephoto's runs): the mean of the spatial map over the
//   pixels of a mask (the completeness mask), NaN when it holds none.
// The masked value over an all-valid mask is the mean of the upsampled maps, which is close to
// but not exactly the whole-image value (bilinear weights at the borders).
//
// Weights: read from the files a user already has, in one directory, under their original
// names (LpipsWeightFiles): the lpips package's linear layers (lpips/weights/v0.1/alex.pth,
// vgg.pth) and torchvision's ImageNet checkpoints (alexnet-owt-7be5be79.pth,
// vgg16-397923af.pth), torch.save files read by torch_file.h. Nothing is downloaded.
//
// Convolutions: oneDNN (Debian's libdnnl 2.6, the library PyTorch's own CPU convolutions run
// on), activations in NHWC, ReLU fused; max pooling by oneDNN too; the normalisation, lin layer,
// means and the upsampling are rephoto's (double accumulation, fixed order). Threads: oneDNN's
// OpenMP threads, as many as the calling TBB arena allows (core ThreadLimit / --threads).
// Determinism: oneDNN's CPU dispatch is capped at AVX2 for the whole process (at the first
// model load), so every AVX2 and AVX-512 CPU, and every REPHOTO_ISA path, runs the same kernels
// and gets bit-identical values; CPUs without AVX2 (pre-2013) run oneDNN's SSE4.1 kernels,
// whose different summation order changes values by about 1e-7 relative (docs/lpips.md).
//
// Memory: both images go through the network stage by stage; their activations live in three
// slots of the largest activation's size (one per image, one for the step being made), kept by
// the calling thread for its next calls (fresh pages cost ~10 us per 4 KiB on first touch).
// The peak, 3 slots plus 8 bytes per pixel of layer maps, is checked against MaxMemoryBytes
// (core/limits.h) before anything is allocated: about 3 x 4 x 64 bytes per input pixel for VGG
// (9 GB at 12 MP), 3 x 4 x 64 / 16 for AlexNet (stride 4: 0.7 GB at 12 MP).
//
// Thread safety: a loaded LpipsModel is immutable; Compute may be called from several threads
// at once (each call its own oneDNN stream and buffers). LoadShared's cache is guarded.
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/core/image.h"
#include "rephoto/metrics/metrics.h"

namespace rephoto::lpips {

enum class LpipsNet { kAlex, kVgg };

// "alex", "vgg".
std::string_view LpipsNetName(LpipsNet net);
// Parses "alex" / "vgg" (also "alexnet", "vgg16"); std::nullopt otherwise.
std::optional<LpipsNet> ParseLpipsNet(std::string_view name);

// The two files the net needs in the weights directory: {lin layers, backbone}:
// alex: {"alex.pth", "alexnet-owt-7be5be79.pth"}; vgg: {"vgg.pth", "vgg16-397923af.pth"}.
std::vector<std::string> LpipsWeightFiles(LpipsNet net);

// The environment variable naming the weights directory when no option does.
inline constexpr const char* kLpipsWeightsEnv = "REPHOTO_LPIPS_WEIGHTS";

// `option` when not empty, else $REPHOTO_LPIPS_WEIGHTS, else empty.
std::filesystem::path LpipsWeightsDirectory(const std::filesystem::path& option);

// The one message for missing weights: which files, where `dir` was looked in (or that no
// directory was given), and how a user with internet access gets them.
std::string MissingWeightsMessage(LpipsNet net, const std::filesystem::path& dir);

struct LpipsValue {
  double whole = 0;       // the whole-image LPIPS (the value the lpips package returns)
  double masked = 0;      // mean of the spatial map over the mask; NaN if no pixel is valid
  size_t masked_pixels = 0;
};

class LpipsModel {
 public:
  // Loads the two files of `net` from `dir`. Throws UsageError with MissingWeightsMessage when
  // `dir` is empty or a file is missing; Error naming the file and tensor when a file is not a
  // torch.save state_dict or a tensor has the wrong shape.
  static std::shared_ptr<const LpipsModel> Load(const std::filesystem::path& dir, LpipsNet net);
  // Load, once per process for each (canonical directory, net); later calls return the same
  // model. Thread-safe.
  static std::shared_ptr<const LpipsModel> LoadShared(const std::filesystem::path& dir,
                                                      LpipsNet net);

  LpipsNet net() const { return net_; }

  // LPIPS between `a` and `b` (same size, RGB or RGBA: alpha ignored; floats in [0,1] or 8-bit
  // v standing for v/255). `mask` (same size; nullptr or empty = all valid) selects the pixels
  // of the masked value. When `spatial_map` is not null it receives the width x height x 1
  // spatial map. With `masked` false (callers that need only the whole-image value, e.g.
  // --compat) and no `spatial_map`, the layer maps are not upsampled: masked is NaN and
  // masked_pixels 0. Throws Error when the sizes differ, the image is too small for the network
  // (AlexNet needs at least 31x31, VGG16 16x16) or the activations would exceed the memory
  // limit.
  LpipsValue Compute(const metrics::RgbView& a, const metrics::RgbView& b, const Mask* mask,
                     Image* spatial_map = nullptr, bool masked = true) const;

  struct Conv {
    int cin = 0, cout = 0, kernel = 0, stride = 1, pad = 0;
    std::vector<float> weight;  // OIHW
    std::vector<float> bias;
  };
  struct Op {
    bool pool = false;
    int conv = -1;                // index into convs (conv + ReLU)
    int pool_kernel = 0, pool_stride = 0;
  };
  struct Stage {
    std::vector<Op> ops;
    int channels = 0;
    std::vector<float> lin;  // channels weights of the 1x1 lin layer
  };

 private:
  LpipsModel() = default;
  LpipsNet net_ = LpipsNet::kAlex;
  std::vector<Conv> convs_;
  std::vector<Stage> stages_;
};

}  // namespace rephoto::lpips
