// Validity masks and completeness (SPEC "Validity and completeness").
//
// - A rephoto pixel is invalid where the renderer covered nothing: alpha == 0 when the image
//   has an alpha channel, otherwise pure black (all colour channels exactly 0), as the paper's
//   benchmark does. An explicit mask overrides both.
// - A photo pixel is invalid where the user mask is 0, or where it is ill-exposed: any colour
//   channel <= dark_threshold or >= saturated_threshold. The defaults flag clipped values
//   (exactly 0 or exactly 1 after scaling to [0,1]); set dark_threshold < 0 and
//   saturated_threshold > 1 to disable the exposure test.
// - Completeness = (windows valid in both photo and rephoto) / (windows valid in the photo),
//   with windows of side `window` (the 1-NCC window, 9 by default; window 1 gives the pixel
//   fraction). Windows that leave the image are not counted. NaN when the photo has no valid
//   window.
//
// Thread safety: pure functions of their inputs; safe to call from several threads at once.
#pragma once

#include "rephoto/core/image.h"

namespace rephoto::metrics {

struct ExposureOptions {
  float dark_threshold = 0.0f;
  float saturated_threshold = 1.0f;
};

// Photo validity from its colour channels (first three; a single grey channel is allowed),
// ANDed with `user_mask` when that is not empty (same size required; throws Error otherwise).
Mask PhotoValidity(const Image& photo, const Mask& user_mask, const ExposureOptions& options = {});
// Same for 8-bit samples as stored in a file (v stands for v / 255, as io::ReadImage converts
// it): the same mask as PhotoValidity of the float image.
Mask PhotoValidity(const Image8& photo, const Mask& user_mask, const ExposureOptions& options = {});

// Rephoto validity: alpha > 0 if the image has 2 or 4 channels, else not all colour channels 0.
// `explicit_mask`, when not empty, is used instead.
Mask RephotoValidity(const Image& rephoto, const Mask& explicit_mask = {});
Mask RephotoValidity(const Image8& rephoto, const Mask& explicit_mask = {});

// Per-pixel AND of two masks of the same size.
Mask CombineMasks(const Mask& a, const Mask& b);

// Window validity: 1 at (x, y) where every pixel of the window x window square centred there
// is valid and inside the image. Cost independent of the window size.
Mask WindowValidity(const Mask& valid, int window);

struct Completeness {
  double value = 0;        // valid_both / valid_photo, NaN if valid_photo == 0
  size_t valid_photo = 0;  // windows valid in the photo
  size_t valid_both = 0;   // windows valid in photo and rephoto
};

Completeness ComputeCompleteness(const Mask& photo_valid, const Mask& rephoto_valid, int window);

}  // namespace rephoto::metrics
