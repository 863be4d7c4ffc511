// 3D Gaussian splatting models (Kerbl et al. 2023) and their file formats.
//
// GaussianModel holds *activated* parameters, in the world frame of the file (rephoto's scene
// conventions, see rephoto/camera/camera.h; the Inria/gsplat/nerfstudio tools write their
// Gaussians in the frame of the COLMAP/transforms.json cameras they were trained on):
// - position: mean, world units.
// - scale: standard deviations along the Gaussian's local axes, world units (exp of the file's
//   log scales).
// - rotation: unit quaternion (w, x, y, z) rotating local axes into the world (the file's
//   rot_0..3 normalised; a zero quaternion becomes the identity, as torch's normalize does).
//   Covariance = R S S^T R^T.
// - opacity: in [0, 1] (sigmoid of the file's logit).
// - sh: real spherical-harmonics coefficients of the colour, (sh_degree + 1)^2 per channel,
//   stored per Gaussian coefficient-major with RGB interleaved: sh[(g * K + k) * 3 + c]
//   (K = coefficients per channel). Colour = max(sum_k SH_k(dir) * sh_k + 0.5, 0) with dir the
//   unit vector from the camera centre to the mean (graphdeco's computeColorFromSH).
//
// Formats read (ReadGaussians; every problem is one rephoto::Error line naming the file and,
// where known, the record and property):
// - Inria PLY (graphdeco 3DGS, gsplat, nerfstudio splatfacto, OpenSplat, Mip-Splatting): binary
//   little/big endian or ascii, element "vertex" with properties found by name: x y z,
//   f_dc_0..2, f_rest_0..f_rest_{n-1} (n = 0, 9, 24 or 45 -> SH degree 0..3; channel-major: the
//   K-1 red coefficients, then green, then blue), opacity (logit), scale_0..2 (log),
//   rot_0..3 (w, x, y, z, any norm). Normals and any other property are ignored, any scalar
//   type is accepted. Mip-Splatting's "filter_3D" is applied as Mip-Splatting does at load:
//   scale' = sqrt(scale^2 + filter^2), opacity' = opacity * sqrt(prod scale^2 / prod scale'^2).
//   splatfacto's colour-only export ("red green blue" instead of f_dc; uchar /255, floats as
//   stored) becomes SH degree 0 with f_dc = (colour - 0.5) / C0.
// - SuperSplat/PlayCanvas compressed PLY: element "chunk" (min/max x y z, min/max scale_x..z
//   as log scales, optional min/max r g b) of 256 Gaussians each, element "vertex" with uint
//   packed_position (11-10-11 bits, lerp in the chunk's box), packed_scale (11-10-11, lerp
//   between the chunk's log scales), packed_rotation (2 bits index of the largest of rot_0..3,
//   then the other three in order, 10 bits each, in [-1/sqrt2, 1/sqrt2]), packed_color
//   (8-8-8-8: RGB lerped in the chunk's colour range, else in [0, 1]; alpha = opacity), and an
//   optional element "sh" of uchar f_rest_* decoded as ((v + 0.5) / 256 - 0.5) * 8 (the
//   centre of splat-transform's quantisation bucket trunc((f / 8 + 0.5) * 256)).
// - antimatter15 ".splat" (by extension): 32-byte records, float32 position[3], float32
//   scale[3] (linear), uint8 RGBA (RGB = colour * 255, A = opacity * 255), uint8 rotation[4]
//   (w, x, y, z as q * 128 + 128); SH degree 0.
// Allocation: counts claimed by a header are checked against the bytes actually present before
// anything is reserved ("claims 1000000 Gaussians (248 bytes each) but holds 4096 bytes").
// Values that are NaN or infinite are rejected.
//
// Thread safety: the functions are reentrant; a GaussianModel is a plain value.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <istream>
#include <string_view>
#include <vector>

namespace rephoto::splat {

// SH basis constants of graphdeco's rasterizer (auxiliary.h).
inline constexpr float kShC0 = 0.28209479177387814f;

struct GaussianModel {
  int sh_degree = 0;  // 0..3
  std::vector<Eigen::Vector3f> positions;
  std::vector<Eigen::Vector3f> scales;
  std::vector<Eigen::Vector4f> rotations;  // (w, x, y, z), unit
  std::vector<float> opacities;
  std::vector<float> sh;  // size() * ShCoefficients() * 3

  size_t size() const { return positions.size(); }
  int ShCoefficients() const { return (sh_degree + 1) * (sh_degree + 1); }
  // Throws Error "<context>: ..." when the arrays disagree in size, sh_degree is outside
  // 0..3, or a value is not finite, a scale negative or an opacity outside [0, 1].
  void Validate(std::string_view context) const;
};

// Which file layout ReadGaussians found (for logging).
enum class GaussianFormat { kInriaPly, kColorPly, kCompressedPly, kSplat };
std::string_view GaussianFormatName(GaussianFormat format);

// Reads a Gaussian model: ".splat" by extension, anything else as PLY (see above).
GaussianModel ReadGaussians(const std::filesystem::path& path, GaussianFormat* format = nullptr);

// The same from a stream (binary mode); `name` prefixes errors, `splat_format` selects the
// 32-byte .splat layout instead of PLY.
GaussianModel ReadGaussians(std::istream& stream, std::string_view name, bool splat_format,
                            GaussianFormat* format = nullptr);

// True when `path` is a ".splat" file, or a PLY whose header declares Gaussian properties
// (vertex opacity + scale_0 + rot_0, or packed_position/packed_rotation: compressed). Reads
// only the header; false for unreadable files and other formats (the mesh reader then reports).
bool IsGaussianFile(const std::filesystem::path& path);

// True when a PLY header (the text up to and including "end_header") declares Gaussians.
bool IsGaussianPlyHeader(std::istream& stream);

// Writes the Inria layout (binary little endian, float32, no normals, f_rest channel-major,
// logit opacity clamped to +-16.1, log scales), for tests, tools and round trips; the path
// version writes atomically. Throws Error when the file cannot be written.
void WriteInriaPly(const std::filesystem::path& path, const GaussianModel& model);
void WriteInriaPly(std::ostream& stream, const GaussianModel& model);

}  // namespace rephoto::splat
