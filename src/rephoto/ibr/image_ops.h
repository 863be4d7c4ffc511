// Small image helpers of the ibr concept (internal; not part of the public API).
//
// Thread safety: pure functions.
#pragma once

#include "rephoto/core/image.h"

namespace rephoto::ibr::internal {

// Shrinks `source` (any channel count) to width x height (each <= the source's) by area
// averaging: an output pixel is the mean of the source area it covers, with exact fractional
// coverage at its borders. Sizes equal to the source's copy it.
Image ShrinkArea(const Image& source, int width, int height);

// Luma 0.299 R + 0.587 G + 0.114 B (grey images are copied; alpha is ignored), 1 channel.
Image Luma(const Image& image);

}  // namespace rephoto::ibr::internal
