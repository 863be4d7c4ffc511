// iCID, the improved colour-image-difference metric of Preiss, Fernandes and Urban,
// "Color-Image Quality Assessment: From Prediction to Optimization", IEEE TIP 23(3), 2014.
// Used through ComputeMetrics (metrics.h); declared here for tests and documentation.
//
// What is implemented (following the authors' reference MATLAB code, iCID.m v1.00, with the
// default "perceptual" intent):
//   - Working colour space: sRGB (IEC 61966-2-1 transfer curve, values clamped to [0,1]) ->
//     XYZ (D65, 2 degree observer) -> CIELAB (D65), with the matrix and white point that
//     scikit-image's rgb2lab uses. NOT the paper's LAB2000HL space: that space is defined by a
//     lookup table shipped with the reference code (LAB2000HL.mat) which we cannot reproduce,
//     so lightness, chroma and hue are measured in CIELAB (L*, C*ab, and the hue difference
//     dH = sqrt(da^2 + db^2 - dC^2)). Values are therefore close to, not equal to, the
//     reference implementation's.
//   - Not implemented: the optional downsampling to ~256 px on the short side and the
//     iCAM/YCC contrast-sensitivity prefilter (the reference code's 'Downsampling' = false and
//     'IAM' = 'NONE' settings). Each error value belongs to the full-resolution pixel.
//   - Seven terms over a normalised 11x11 Gaussian window (sigma 2), with the reference
//     constants: lightness difference 1/(1 + 0.002 dL^2), lightness contrast
//     (10 + 2 sL1 sL2)/(10 + sL1^2 + sL2^2), lightness structure (10 + |sL12|)/(10 + sL1 sL2)
//     raised to the power 3, chroma difference 1/(1 + 0.002 dC^2), hue difference
//     1/(1 + 0.002 dH^2) with dH the window mean of the per-pixel hue difference, chroma
//     contrast and chroma structure like the lightness ones with C* instead of L* (constants
//     10, exponent 1). Error per window = 1 - product of the seven terms, in [0, 1].
//     |s12| is limited to s1 s2 (Cauchy-Schwarz), which only removes rounding noise and makes
//     identical images give exactly 0. CIELAB is computed in float (L* within ~1e-5, a* and b*
//     within ~1e-4 of the double formulas of SrgbToLab; error values move by up to ~1e-6), the
//     window sums and the terms in double.
//
// Thread safety: pure functions of their inputs; safe to call from several threads at once.
#pragma once

#include <cstddef>

#include "rephoto/core/image.h"

namespace rephoto::metrics {

struct IcidOptions {
  int window = 11;     // odd
  double sigma = 2.0;  // Gaussian sigma in pixels
};

// CIELAB (D65) of one sRGB colour given in [0,1] (clamped); L in [0,100].
void SrgbToLab(float r, float g, float b, double lab[3]);

namespace internal {
// What ComputeIcid runs, for tests. CIELAB is computed in float (icid.cc LinearToLabRow): planar
// linear RGB (r, g, b planes of w values in [0, 1], the sRGB transfer curve already undone) to
// planar L, a, b planes of w floats; the cube root without libm (CubeRootFloat, positive normal
// floats below 2^42).
void LinearRgbToLabFloat(const double* linear, int w, float* lab);
float CubeRootFloat(float x);
}  // namespace internal

// Writes the iCID error image (1 channel, NaN where the window is not entirely valid or leaves
// the image) into `error` (already sized width x height x 1), and the mean over evaluated
// windows and their count. `valid` may be empty (all valid).
void ComputeIcid(const Image& photo, const Image& rephoto, const Mask& valid,
                 const IcidOptions& options, Image* error, double* mean, size_t* evaluated);

}  // namespace rephoto::metrics
