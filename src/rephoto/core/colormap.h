// Colour maps for error visualization.
//
// Thread safety: pure functions.
#pragma once

#include <array>

#include "rephoto/core/image.h"

namespace rephoto {

// MATLAB's "jet" colour map: t in [0,1] (clamped) -> RGB in [0,1]; 0 dark blue, 0.5 green-
// yellow, 1 dark red. NaN maps to black.
std::array<float, 3> JetColor(float t);

// Maps a 1-channel image linearly from [low, high] to [0,1] and through JetColor. Returns RGBA:
// alpha 0 (and black) where the value is NaN (not evaluated), 1 elsewhere.
Image ApplyJet(const Image& values, float low, float high);

}  // namespace rephoto
