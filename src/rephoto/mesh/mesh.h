// Meshes and point clouds: the one geometry type rephoto renders, colours and writes.
//
// A Mesh is an indexed triangle mesh; without faces it is a point cloud. All attributes are
// optional except positions; an attribute vector is either empty (absent) or has exactly the
// size stated next to it (Validate() checks this).
//
// Conventions:
// - Positions, normals, radii: in the model's world frame and units, as stored in the file.
//   Normals are whatever the file gives (not renormalized by readers).
// - Colours: RGB float in [0,1], values as stored (display-referred, no linearization);
//   8-bit files are converted v/255 (16-bit v/65535) at the I/O boundary and back by rounding.
// - Faces: triangles, vertex indices into `positions`, counter-clockwise seen from the front:
//   the face normal (p1 - p0) x (p2 - p0) points to the front side. Readers triangulate polygons
//   with a fan (v0, vi, vi+1).
// - Texture coordinates (u, v) follow OpenGL/OBJ/PLY: u = 0 the left edge, u = 1 the right edge,
//   v = 0 the bottom edge, v = 1 the top edge of the texture image; outside [0,1] the texture
//   repeats. Either per vertex (`vertex_texcoords`) or per wedge (`wedge_texcoords`, three per
//   face, in the face's vertex order, as OpenMVS/MeshLab write them); wedges win when both exist.
// - Materials: `face_materials[f]` indexes `materials` (-1 = none); when `face_materials` is
//   empty every face uses material 0 if there is one (a PLY with one TextureFile). A material has a
//   diffuse colour and optionally a diffuse texture image (absolute path, or relative to the
//   current directory, resolved by the reader against the model file's folder).
//
// Thread safety: plain value types without synchronization: any number of threads may read a Mesh
// at once; a Mesh being modified must not be read or modified by another thread.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace rephoto::mesh {

using Triangle = std::array<uint32_t, 3>;

struct Material {
  std::string name;
  Eigen::Vector3f diffuse = Eigen::Vector3f::Ones();  // RGB in [0,1]
  std::filesystem::path diffuse_texture;              // empty = no texture
};

// A named per-vertex float attribute (e.g. an error value or PLY "quality").
struct VertexScalar {
  std::string name;
  std::vector<float> values;  // one per vertex
};

struct Mesh {
  std::vector<Eigen::Vector3f> positions;         // required, size V
  std::vector<Eigen::Vector3f> normals;           // empty or V
  std::vector<Eigen::Vector3f> colors;            // empty or V, RGB in [0,1]
  std::vector<float> radii;                       // empty or V: point (splat) radius, > 0
  std::vector<Eigen::Vector2f> vertex_texcoords;  // empty or V
  std::vector<Triangle> faces;                    // F triangles (0 = point cloud)
  std::vector<Eigen::Vector2f> wedge_texcoords;   // empty or 3F, in face vertex order
  std::vector<int> face_materials;                // empty or F: index into materials, -1 none
  std::vector<Material> materials;
  std::vector<VertexScalar> scalars;  // extra per-vertex float attributes

  size_t vertex_count() const { return positions.size(); }
  size_t face_count() const { return faces.size(); }
  bool is_point_cloud() const { return faces.empty(); }
  bool has_texcoords() const { return !wedge_texcoords.empty() || !vertex_texcoords.empty(); }
  // True when some material has a diffuse texture and the mesh has texture coordinates.
  bool is_textured() const;
  // Appends `scalar`, replacing (dropping) a scalar of the same name.
  void SetScalar(VertexScalar scalar);

  // Texture coordinate of corner `corner` (0..2) of face `face` (wedge, else per vertex).
  // Precondition: has_texcoords().
  Eigen::Vector2f Texcoord(size_t face, int corner) const {
    return wedge_texcoords.empty() ? vertex_texcoords[faces[face][corner]]
                                   : wedge_texcoords[3 * face + corner];
  }

  // Material index of a face (see the convention above); -1 = none.
  int FaceMaterial(size_t face) const {
    if (!face_materials.empty()) return face_materials[face];
    return materials.empty() ? -1 : 0;
  }

  // Throws rephoto::Error, prefixed with `context` (usually the file name), when the mesh has no
  // vertices, a position is NaN/inf, a face indexes a missing vertex, an attribute vector has
  // the wrong size, a radius is not positive and finite, or a face material index is out of
  // range. Messages name the element: "<context>: face 12: vertex index 99 out of range (50
  // vertices)".
  void Validate(std::string_view context) const;
};

// Area-weighted per-vertex normals from the faces (unit length; zero for vertices in no face
// or only in degenerate faces). Orientation follows the face winding.
std::vector<Eigen::Vector3f> ComputeVertexNormals(const Mesh& mesh);

// Axis-aligned bounding box of the positions: {min, max}. Precondition: non-empty.
std::array<Eigen::Vector3f, 2> BoundingBox(const Mesh& mesh);

}  // namespace rephoto::mesh
