// Surfaces with closed-form geometry, for tests and benchmarks of the geometric evaluation.
// All faces are counter-clockwise seen from outside (normals point away from the centre).
// Every vertex of a sphere or hemisphere lies exactly on it (up to float rounding); the faces lie
// inside by at most the sagitta, which TessellationError measures.
// Thread safety: pure functions.
#pragma once

#include <Eigen/Core>

#include "rephoto/mesh/mesh.h"

namespace rephoto::geometry {

// Icosahedron subdivided `subdivisions` times (20 * 4^s faces), vertices projected to the sphere.
mesh::Mesh MakeIcosphere(double radius, int subdivisions,
                         const Eigen::Vector3d& center = Eigen::Vector3d::Zero());

// Latitude-longitude sphere: `rings` bands of latitude (>= 2) and `segments` of longitude (>= 3);
// triangle fans at the poles, 2 * segments * (rings - 1) faces.
mesh::Mesh MakeUvSphere(double radius, int rings, int segments,
                        const Eigen::Vector3d& center = Eigen::Vector3d::Zero());

// The upper half (z >= centre z) of MakeUvSphere with 2 * rings bands: `rings` bands from the
// pole down to the equator, whose rim lies exactly on the plane z = centre z.
mesh::Mesh MakeUvHemisphere(double radius, int rings, int segments,
                            const Eigen::Vector3d& center = Eigen::Vector3d::Zero());

// The rectangle [x0, x1] x [y0, y1] at height z as 2 triangles, facing +z.
mesh::Mesh MakeRectangle(double x0, double y0, double x1, double y1, double z);

// max over faces of (radius - distance from `center` to the face): how far the tessellated
// sphere lies inside the true one (the sagitta); 0 for an exact sphere.
double TessellationError(const mesh::Mesh& sphere, double radius, const Eigen::Vector3d& center);

}  // namespace rephoto::geometry
