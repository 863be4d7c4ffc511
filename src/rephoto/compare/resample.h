// Rescaling renderings to their photo's size (`rephoto compare --resize`).
//
// Each axis is resampled independently (separable). When an axis shrinks, an output pixel is the
// area-weighted mean of the source pixels its footprint covers (a box filter with exact
// fractional coverage, "area" interpolation); when it grows, it is bilinear between source
// pixel centres (pixel (i) has its centre at i + 0.5; clamped at the borders); an axis whose
// size does not change is copied. This avoids the aliasing of nearest or plain bilinear
// sampling when shrinking.
// Masks are resampled conservatively: an output pixel is valid only when every source pixel
// with a nonzero weight in it is valid, so resized colours never mix covered and uncovered
// pixels of a rendering.
//
// Thread safety: reentrant (parallelizes inside, core/parallel.h).
#pragma once

#include "rephoto/core/image.h"

namespace rephoto::compare {

// Resamples `source` (any channel count) to width x height into `target` (reusing its
// allocation). Throws Error when a size is not positive.
void ResizeImage(const Image& source, int width, int height, Image* target);

// Conservative mask resampling (see above); output values are 0 or 1.
void ResizeMask(const Mask& source, int width, int height, Mask* target);

}  // namespace rephoto::compare
