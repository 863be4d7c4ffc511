// Gaussian models with a per-Gaussian value added, for `rephoto project` and `evaluate`'s error
// projection onto Gaussian splatting models.
//
// The output keeps every property of the original file and adds one float32 vertex property
// (e.g. "error"), so SuperSplat, MeshLab and CloudCompare open it as they opened the model and
// can colour by the new property:
// - A binary little-endian PLY whose only element is "vertex" (the Inria layout as graphdeco,
//   gsplat, nerfstudio and OpenSplat write it) is copied byte for byte, each record followed by
//   the 4 bytes of its value; the header gains "property float <name>" after the last vertex
//   property. A float property of that name already there (a file projected before) is
//   overwritten in place instead.
// - Anything else (SuperSplat's compressed PLY, .splat, ascii or big-endian PLY) is first
//   written in the Inria layout (WriteInriaPly, the Gaussians as rephoto rendered them), then
//   extended as above.
// Values are one per Gaussian in file order; NaN marks a Gaussian no view saw.
//
// Thread safety: reentrant.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/splat/gaussians.h"

namespace rephoto::splat {

// The bytes of `ply` (a binary little-endian PLY with one "vertex" element of fixed-size
// records) with the float property `name` set to `values`. Throws Error "<context>: ..." when
// the PLY is not of that kind or its vertex count differs from values.size().
std::string WithVertexFloatProperty(std::string_view ply, std::string_view name,
                                    const std::vector<float>& values, std::string_view context);

// Writes `model` read from `source` with the property added (see above), atomically to `out`.
void WriteGaussiansWithScalar(const std::filesystem::path& source, const GaussianModel& model,
                              std::string_view name, const std::vector<float>& values,
                              const std::filesystem::path& out);

}  // namespace rephoto::splat
