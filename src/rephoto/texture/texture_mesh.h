// Texturing a mesh from calibrated photos, in the manner of Waechter, Moehrle and Goesele 2014
// ("Let there be color! Large-scale texturing of 3D reconstructions", ECCV): the textured mesh
// is the representation that looks best in the virtual rephotography paper's Table I.
//
// Stages (each file's header has the details):
// 1. Visibility and data term (view_selection.h): for every face and photo, whether the photo
//    sees the whole face (facing, inside the image with the camera's distortion, four Embree
//    occlusion rays: the renderer's BVH), and the face's quality there: the gradient magnitude
//    integral over its projection plus a per-pixel floor (close, frontal and sharp views win).
//    Faces that no photo sees whole (large faces of coarse meshes) may take a photo that sees
//    part of them (`partial_min_fraction`); their texels hidden in that photo come from the
//    photo that sees them best (atlas.h).
// 2. Photo-consistency check (view_selection.h): per face, views whose mean colour is far
//    from the mean-shift mode of all its views' colours are dropped (they see an occluder).
// 3. View selection as a Potts MRF over faces sharing an edge (mrf.h): data cost
//    1 - quality / q99, smoothness `smoothness` per differing neighbour pair, minimized by
//    alpha-expansion with Boykov-Kolmogorov max-flow.
// 4. Global colour adjustment across seams (leveling.h): per-vertex, per-view additive offsets
//    from a sparse least-squares problem (conjugate gradients). The paper's second, local
//    Poisson blending step is not done: the global offsets already join both sides of a seam
//    in colour; what remains at a seam is texture detail that differs between two photos.
// 5. Patches (connected faces with the same view) cut from their photos at the photo's
//    resolution times `texel_scale`, with padding, packed into RGB atlases (atlas.h).
// Faces that no photo sees (no candidate) get the colour of the nearest textured face (breadth
// first over faces sharing an edge: the textured face reached first; its colour is its mean
// colour in its photo plus its seam adjustment) as a 4x4 single-colour atlas cell: "filled".
// Unseen faces in a part of the mesh without any textured face get mid grey (0.5): "default".
//
// Units and conventions: positions and cameras as in camera/camera.h and mesh/mesh.h; colours
// RGB in [0,1] as stored in the photos (no linearization), atlases 8-bit. Texture coordinates
// per wedge, OBJ/OpenGL convention (u right, v up, (0,0) the bottom-left corner of the atlas
// image), all in [0,1] (atlas.h). Photos are read with io::ReadImage8 (JPEG, PNG, EXR, PFM; grey
// replicated, alpha ignored), a photo whose size differs from its camera's with the camera
// scaled to it (Camera::Scaled), as colorize.h does.
// Deterministic: the result does not depend on the thread count. Not thread-safe to share a
// TexturedMesh being written; TextureMesh itself may run concurrently on different inputs.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "rephoto/core/image.h"
#include "rephoto/mesh/mesh.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/scene/scene.h"

namespace rephoto::texture {

struct TextureOptions {
  // Visibility and data term.
  double min_facing_cosine = 0.05;  // a photo sees a face only above this cosine
  double occlusion_epsilon = 1e-3;  // relative length of occlusion rays left out at the face
  double gradient_floor = 0.02;     // added per pixel to the gradient magnitude (see above)
  // Faces no photo sees whole may take a photo that sees at least this fraction of their
  // sample points (view_selection.h; 0 = only whole views, as the paper).
  double partial_min_fraction = 0.5;
  // Photo-consistency check.
  bool photo_consistency = true;
  double consistency_bandwidth = 0.1;      // mean-shift kernel, RGB units
  double consistency_min_threshold = 0.1;  // never drop a view closer than this to the mode
  // View selection.
  float smoothness = 1.0f;  // Potts weight, data costs are in [0, 1]
  int mrf_cycles = 4;
  // Seam adjustment.
  bool seam_leveling = true;
  double leveling_smoothness = 1.0;
  // Atlases.
  double texel_scale = 1.0;  // texels per photo pixel, (0, 1]
  int max_atlas_size = 8192;
  int padding = 2;
  bool show_progress = false;  // a Progress line per photo while testing visibility

  // Throws UsageError naming the setting that is out of range.
  void Check() const;
};

// What TextureMesh did; WriteTextureReport writes it as JSON (keys = field names).
struct TextureReport {
  size_t vertices = 0;
  size_t faces = 0;
  size_t views_given = 0;     // photos offered
  size_t views_used = 0;      // photos that texture at least one face
  size_t visible_faces = 0;   // seen by at least one photo (after the consistency check)
  size_t textured_faces = 0;  // faces with texels from a photo (= visible_faces)
  size_t partial_faces = 0;   // of those, textured from a photo that sees only part of them
  size_t filled_faces = 0;    // unseen faces coloured from the nearest textured face
  size_t default_faces = 0;   // unseen faces without any textured face connected: grey
  size_t candidates = 0;      // visible (face, photo) pairs
  size_t inconsistent_candidates = 0;  // of those, dropped by the photo-consistency check
  double mrf_initial_energy = 0;       // every face at its best photo
  double mrf_energy = 0;               // after alpha-expansion
  size_t mrf_moves = 0;
  size_t patches = 0;
  size_t seam_vertices = 0;
  int leveling_iterations = 0;
  size_t atlases = 0;
  size_t atlas_texels = 0;
  size_t reassigned_texels = 0;  // texels of partial faces hidden in their photo, from another
  // Wall-clock seconds per stage.
  double seconds_visibility = 0;  // photo decoding, gradients, ray casting, data term
  double seconds_consistency = 0;
  double seconds_selection = 0;  // MRF
  double seconds_leveling = 0;   // includes decoding the seam photos
  double seconds_atlas = 0;      // includes decoding the used photos
  double seconds_total = 0;
};

struct TexturedMesh {
  // The input's positions, faces and normals, with wedge texture coordinates, face_materials
  // (the atlas of each face) and one material per atlas ("atlas_<i>", diffuse 1, no texture
  // path: the writers set it to the atlas file they write).
  mesh::Mesh mesh;
  std::vector<Image8> atlases;  // RGB
  std::vector<int> face_views;  // scene view index texturing each face, -1 = filled/default
  TextureReport report;
};

// Textures `mesh` (triangles; colours and texture coordinates it may have are ignored) from the
// photos of scene.views[i] for i in `view_indices` (e.g. one fold's training views). Throws
// Error for an invalid mesh (Mesh::Validate, context "mesh"), a mesh without faces, a view
// index out of range, an unreadable photo (naming the file), UsageError for bad options.
TexturedMesh TextureMesh(const mesh::Mesh& mesh, const scene::Scene& scene,
                         const std::vector<size_t>& view_indices,
                         const TextureOptions& options = {});

// Writes OBJ + MTL + PNG atlases: `path` (…/NAME.obj), NAME.mtl and NAME_atlas_<i>.png beside
// it. The OBJ has "mtllib NAME.mtl", v, vt (u, v in [0,1], OBJ convention: v = 0 is the
// bottom row of the image), "usemtl atlas_<i>" and f v/vt; the MTL has per atlas "newmtl
// atlas_<i>", Kd 1 1 1 and "map_Kd NAME_atlas_<i>.png" (relative: the folder can be moved).
// Every file is written atomically (temporary name + rename), the OBJ last, so the OBJ never
// names a missing file. Throws Error naming a file that cannot be written.
void WriteTexturedObj(const std::filesystem::path& path, const TexturedMesh& textured);

// Writes a PLY with per-face texture coordinates ("texcoord" lists, as MeshLab and OpenMVS),
// "texnumber" and one "comment TextureFile NAME_atlas_<i>.png" per atlas, and the atlases
// (the same names as WriteTexturedObj), atomically, the PLY last.
void WriteTexturedPly(const std::filesystem::path& path, const TexturedMesh& textured,
                      mesh::PlyEncoding encoding = mesh::PlyEncoding::kBinaryLittleEndian);

// The report as JSON text ("schema": "rephoto.texture/1", then the fields above) and as a
// file (atomic).
std::string TextureReportJson(const TextureReport& report);
void WriteTextureReport(const std::filesystem::path& path, const TextureReport& report);

}  // namespace rephoto::texture
