// Texture patches and atlases (Waechter, Moehrle and Goesele 2014, Sec. 5), internal to texture/.
//
// Patches: the connected components (faces sharing an edge) of faces with the same view label.
// Each patch's texels are the region of its photo that its faces project to (corners projected
// with the camera's distortion; the faces' edges are straight lines between them), at
// `texel_scale` texels per photo pixel (1 = the photo's own resolution; a patch wider or
// higher than the atlas is scaled down to fit), with `padding` texels of the surrounding photo
// on every side so that bilinear and mip-mapped lookups near a patch border read photo
// content of the same surface rather than another patch. Texel value = the photo sampled
// bilinearly at the texel centre + the seam adjustment (leveling.h), interpolated
// barycentrically over the face that covers the texel centre; texels outside every face take
// the adjustment of the nearest covered texel (dilation), or the patch mean beyond that.
// Faces without a label get a 4x4 cell of one colour (fill_colors), with all three texture
// coordinates at the cell centre.
// Packing: patches sorted by height (then width, then patch order) on shelves, left to right,
// in atlases `max_atlas_size` texels wide (less when everything fits in a smaller power of
// two); an atlas that is full starts the next one. Atlas height = the used height.
// Texture coordinates (OBJ/OpenGL convention, mesh.h): u = x / width, v = 1 - y / height, with
// (x, y) the position in atlas texels (pixel-corner convention: texel (i, j) covers
// [i, i+1) x [j, j+1)), y down from the image's top row; all in [0, 1].
//
// Thread safety: functions of their arguments; parallel inside, deterministic.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <vector>

#include "rephoto/core/image.h"
#include "rephoto/mesh/mesh.h"
#include "rephoto/render/render_model.h"
#include "rephoto/scene/scene.h"
#include "rephoto/texture/leveling.h"

namespace rephoto::texture {

struct AtlasOptions {
  double texel_scale = 1.0;  // texels per photo pixel, (0, 1]
  int max_atlas_size = 8192;
  int padding = 2;
  double occlusion_epsilon = 1e-3;  // as view_selection.h
};

struct Atlases {
  std::vector<Image8> images;                    // RGB, 8 bits
  std::vector<Eigen::Vector2f> wedge_texcoords;  // 3 per face
  std::vector<int> face_atlas;                   // per face: index into images
  size_t patches = 0;
  size_t fill_cells = 0;
  size_t texels = 0;             // sum of the atlases' areas
  size_t reassigned_texels = 0;  // texels of partially seen faces coloured from another photo
};

// Faces textured from a photo that sees only part of them (partial_faces[f] != 0,
// view_selection.h): each texel whose point that photo does not see (outside it, or an
// occlusion ray through the model's BVH is blocked) takes the colour of the photo that sees the
// point best (facing, unoccluded; largest cos x (focal / distance)^2), so an occluder in front
// of part of the face is not painted onto it; texels no photo sees keep their photo's colour.
// face_labels: position in `views` per face (-1 = none); fill_colors: per face, used for the
// faces with label -1. Reads each used photo once (every photo once more when some texels of
// partially seen faces are hidden). Throws Error naming a photo that cannot be read.
Atlases BuildAtlases(const mesh::Mesh& mesh,
                     const std::vector<std::pair<uint32_t, uint32_t>>& face_pairs,
                     const std::vector<int>& face_labels,
                     const std::vector<Eigen::Vector3f>& fill_colors,
                     const ColorAdjustment& adjustment, const render::RenderModel& model,
                     const std::vector<uint8_t>& partial_faces, const scene::Scene& scene,
                     const std::vector<size_t>& views, const AtlasOptions& options);

}  // namespace rephoto::texture
