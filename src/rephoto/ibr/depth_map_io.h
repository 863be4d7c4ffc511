// Per-view depth maps: reading and writing the formats image-based rendering takes.
//
// A depth map is a 1-channel rephoto::Image holding the camera-frame z (not the ray length) of
// the surface seen through each pixel, in scene units, NaN where unknown. It belongs to one
// view and covers that view's image: pixel (x, y) of a depth map of size w x h corresponds to
// the view's pixel position ((x + 0.5) * W / w, (y + 0.5) * H / h) for a W x H photo (the
// camera scaled to the depth map, Camera::Scaled), so depth maps may have a lower resolution
// than the photos. They are given in the view's own (possibly distorted) pixel grid: depth maps
// of COLMAP's dense workspace belong to its undistorted images and PINHOLE cameras
// (dense/sparse), so pair them with those cameras.
//
// Formats (detected by content, not by extension):
// - COLMAP `stereo/depth_maps/*.bin` (colmap/mvs/mat.{h,cc}, Mat<float>::Read/Write): an ASCII
//   header "<width>&<height>&<channels>&" (decimal integers, each followed by '&'; COLMAP
//   reads it with operator>>, so leading whitespace before a number is tolerated), then
//   width * height * channels float32 little-endian values, channel-major then row-major:
//   value (col, row, channel) at index channel * width * height + row * width + col. Depth
//   maps have 1 channel (normal maps 3; the first channel is used). COLMAP writes 0 for
//   unknown depth.
// - PFM ("Pf" grey or "PF" RGB: the first channel) and OpenEXR (the first channel), read by
//   rephoto::io::ReadImage.
// Values <= 0 or non-finite become NaN (unknown).
//
// Thread safety: reentrant; concurrent writes must go to different paths.
#pragma once

#include <filesystem>
#include <istream>
#include <string>

#include "rephoto/core/image.h"

namespace rephoto::ibr {

// Reads a depth map in any of the formats above. Throws Error "<path>: <what is wrong>" for a
// missing or unreadable file, a bad COLMAP header (non-numeric, zero or absurd sizes, missing
// '&'), a truncated payload, or an image without channels. The size in the header is checked
// against --max-pixels and --max-memory (core/limits.h) and, when the stream can tell, against
// the bytes that follow, before the depth map is allocated.
Image ReadDepthMap(const std::filesystem::path& path);

// COLMAP .bin reader on a stream; `name` is used in error messages. Trailing bytes after the
// payload are an error too (a sign of a wrong size in the header).
Image ReadColmapDepthMap(std::istream& in, const std::string& name);

// Writes a 1-channel depth map in COLMAP's .bin format (NaN and values <= 0 are written as 0,
// COLMAP's "unknown"), atomically. Throws Error if `depth` does not have 1 channel or on a
// write error.
void WriteColmapDepthMap(const std::filesystem::path& path, const Image& depth);

}  // namespace rephoto::ibr
