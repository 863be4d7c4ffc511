// Middlebury multi-view stereo camera files (*_par.txt, Seitz et al. 2006,
// https://vision.middlebury.edu/mview/data/).
//
// Format: first content line = number of images n; then n lines
//   "imgname.png k11 k12 k13 k21 k22 k23 k31 k32 k33 r11 r12 r13 r21 r22 r23 r31 r32 r33 t1 t2 t3"
// with the projection x ~ K [R | t] X: R, t map world to camera (x right, y down, looking along
// +z, as rephoto), K is row-major. Image names are relative to the folder of the file.
//
// Conversions to rephoto (camera/camera.h):
// - Pixel convention: the README only says "the image origin is top-left". We read K as the
//   usual computer-vision (OpenCV/Bouguet) matrix where integer coordinates are pixel centres,
//   so the principal point gets +0.5 (centre of the first pixel = (0.5, 0.5)). This is an
//   assumption the data cannot confirm at sub-pixel level.
// - Each view gets a PINHOLE camera (fx, fy, cx + 0.5, cy + 0.5); identical ones are shared.
//   K must be upper triangular with zero skew and k33 != 0 (it is divided by k33).
// - The file stores no image size: it comes from the image files (ImageSizeLookup).
//
// Thread safety: reentrant (no shared state); the ImageSizeLookup given is called from the calling
// thread only.
#pragma once

#include <filesystem>
#include <istream>
#include <string_view>

#include "rephoto/scene/reader_util.h"
#include "rephoto/scene/scene.h"

namespace rephoto::scene {

// Parses a *_par.txt stream (named `name` in errors). Throws Error "<name>:<line>: ..." on
// wrong counts, NaN/inf, non-rotations, skew, duplicate image names, truncation.
Scene ReadMiddlebury(std::istream& in, std::string_view name, const ImageSizeLookup& image_sizes,
                     const std::filesystem::path& image_root);

// Reads a *_par.txt file; images are relative to its folder, sizes from the image headers.
Scene ReadMiddleburyScene(const std::filesystem::path& par_path);

}  // namespace rephoto::scene
