#include "rephoto/render/render.h"

#include <gmock/gmock.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "rephoto/core/error.h"
#include "rephoto/core/isa.h"
#include "rephoto/io/image_io.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/render/point_radius.h"
#include "rephoto/testing/testing.h"

namespace rephoto::render {
namespace {

using camera::Camera;
using camera::CameraModel;
using camera::Pose;

Camera MakePinhole(int width, int height, double f, double cx, double cy) {
  Camera camera;
  camera.model = CameraModel::kPinhole;
  camera.width = width;
  camera.height = height;
  camera.params = {f, f, cx, cy};
  return camera;
}

// One triangle, tilted so that depth varies over it, with red/green/blue corners.
mesh::Mesh MakeTriangle(bool front_facing_camera = true) {
  mesh::Mesh mesh;
  mesh.positions = {Eigen::Vector3f(-0.83f, -0.61f, 2.0f), Eigen::Vector3f(0.91f, -0.37f, 2.6f),
                    Eigen::Vector3f(-0.13f, 0.77f, 3.1f)};
  mesh.colors = {Eigen::Vector3f(1, 0, 0), Eigen::Vector3f(0, 1, 0), Eigen::Vector3f(0, 0, 1)};
  mesh.faces = {{0, 1, 2}};
  // (p1 - p0) x (p2 - p0) must point towards the camera (negative z) for a front face.
  const Eigen::Vector3f n =
      (mesh.positions[1] - mesh.positions[0]).cross(mesh.positions[2] - mesh.positions[0]);
  if ((n.z() < 0) != front_facing_camera) mesh.faces = {{0, 2, 1}};
  return mesh;
}

// Closed form, in double precision: the ray (xn, yn, 1) from the origin against the triangle.
// Returns barycentrics (b0, b1, b2) and the depth z; `margin` receives the smallest barycentric
// (negative outside; near 0 means the sample is on an edge and ambiguous).
bool IntersectClosedForm(const mesh::Mesh& mesh, double xn, double yn, Eigen::Vector3d* bary,
                         double* z, double* margin) {
  const Eigen::Vector3d p0 = mesh.positions[0].cast<double>();
  const Eigen::Vector3d p1 = mesh.positions[1].cast<double>();
  const Eigen::Vector3d p2 = mesh.positions[2].cast<double>();
  const Eigen::Vector3d d(xn, yn, 1);
  // Solve p0 + b1 (p1 - p0) + b2 (p2 - p0) = t d.
  Eigen::Matrix3d a;
  a << p1 - p0, p2 - p0, -d;
  const Eigen::Vector3d x = a.colPivHouseholderQr().solve(-p0);
  *bary = Eigen::Vector3d(1 - x(0) - x(1), x(0), x(1));
  *z = x(2);  // d.z = 1
  *margin = bary->minCoeff();
  return *margin >= 0;
}

TEST(RenderTest, TriangleCoversExactlyThePixelCentresInside) {
  const Camera camera = MakePinhole(80, 60, 70.0, 40.3, 29.7);
  for (bool front : {true, false}) {
    const mesh::Mesh mesh = MakeTriangle(front);
    RenderModel model(mesh);
    ASSERT_EQ(model.representation(), Representation::kVertexColoredMesh);
    RenderOptions options;
    options.samples_per_pixel = 1;
    const Rephoto r = RenderRephoto(model, camera, Pose(), options);
    ASSERT_EQ(r.color.width(), 80);
    ASSERT_EQ(r.color.channels(), 4);
    int inside = 0, ambiguous = 0;
    for (int y = 0; y < 60; ++y) {
      for (int x = 0; x < 80; ++x) {
        const double xn = (x + 0.5 - 40.3) / 70.0, yn = (y + 0.5 - 29.7) / 70.0;
        Eigen::Vector3d bary;
        double z, margin;
        const bool hit = IntersectClosedForm(mesh, xn, yn, &bary, &z, &margin);
        if (std::abs(margin) < 1e-5) {
          ++ambiguous;
          continue;
        }
        ASSERT_EQ(r.color.at(x, y, 3), hit ? 1.0f : 0.0f) << x << "," << y;
        if (!hit) {
          EXPECT_TRUE(std::isnan(r.depth.at(x, y)));
          EXPECT_EQ(r.color.at(x, y, 0), 0.0f);
          continue;
        }
        ++inside;
        // Corner colours are the unit vectors, so the colour is the barycentric vector.
        const Eigen::Vector3d expected = front ? bary : Eigen::Vector3d(bary(0), bary(1), bary(2));
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(r.color.at(x, y, c), expected(c), 2e-5);
        EXPECT_NEAR(r.depth.at(x, y), z, 2e-5 * z);
      }
    }
    EXPECT_EQ(ambiguous, 0);
    EXPECT_GT(inside, 500);
  }
}

TEST(RenderTest, BackfacesCanBeCulled) {
  const Camera camera = MakePinhole(40, 30, 35.0, 20, 15);
  RenderOptions options;
  options.samples_per_pixel = 1;
  options.backfaces = false;
  RenderModel front(MakeTriangle(true));
  RenderModel back(MakeTriangle(false));
  const Rephoto a = RenderRephoto(front, camera, Pose(), options);
  const Rephoto b = RenderRephoto(back, camera, Pose(), options);
  double coverage_a = 0, coverage_b = 0;
  for (int y = 0; y < 30; ++y) {
    for (int x = 0; x < 40; ++x) {
      coverage_a += a.color.at(x, y, 3);
      coverage_b += b.color.at(x, y, 3);
    }
  }
  EXPECT_GT(coverage_a, 50);
  EXPECT_EQ(coverage_b, 0);
  options.backfaces = true;
  const Rephoto c = RenderRephoto(back, camera, Pose(), options);
  double coverage_c = 0;
  for (int y = 0; y < 30; ++y) {
    for (int x = 0; x < 40; ++x) coverage_c += c.color.at(x, y, 3);
  }
  EXPECT_EQ(coverage_c, coverage_a);
}

// Twice the signed area of a 2D triangle.
double Area2(const Eigen::Vector2d& a, const Eigen::Vector2d& b, const Eigen::Vector2d& c) {
  return (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
}

TEST(RenderTest, CoverageWithManySamplesMatchesProjectedArea) {
  const Camera camera = MakePinhole(80, 60, 70.0, 40.3, 29.7);
  const mesh::Mesh mesh = MakeTriangle();
  RenderModel model(mesh);
  // Projected triangle area in pixels (a straight-edged triangle under a pinhole camera).
  Eigen::Vector2d q[3];
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d p = mesh.positions[k].cast<double>();
    q[k] = Eigen::Vector2d(70.0 * p.x() / p.z() + 40.3, 70.0 * p.y() / p.z() + 29.7);
  }
  const double area = std::abs(Area2(q[0], q[1], q[2])) / 2;
  for (SamplePattern pattern : {SamplePattern::kStratifiedJittered, SamplePattern::kRegular}) {
    RenderOptions options;
    options.samples_per_pixel = 16;
    options.pattern = pattern;
    const Rephoto r = RenderRephoto(model, camera, Pose(), options);
    double coverage = 0;
    for (int y = 0; y < 60; ++y) {
      for (int x = 0; x < 80; ++x) coverage += r.color.at(x, y, 3);
    }
    EXPECT_NEAR(coverage, area, 0.01 * area) << static_cast<int>(pattern);
    // Deterministic: the same call gives the same image.
    const Rephoto again = RenderRephoto(model, camera, Pose(), options);
    EXPECT_EQ(std::memcmp(r.color.data(), again.color.data(), r.color.size() * sizeof(float)), 0);
  }
}

TEST(RenderTest, SampleOffsetsAreStratified) {
  RenderOptions options;
  options.samples_per_pixel = 4;
  for (int s = 0; s < 4; ++s) {
    const Eigen::Vector2f o = SampleOffset(7, 9, s, options);
    EXPECT_GE(o.x(), 0.5f * (s % 2));
    EXPECT_LT(o.x(), 0.5f * (s % 2) + 0.5f);
    EXPECT_GE(o.y(), 0.5f * (s / 2));
    EXPECT_LT(o.y(), 0.5f * (s / 2) + 0.5f);
  }
  options.samples_per_pixel = 1;
  EXPECT_EQ(SampleOffset(3, 4, 0, options), Eigen::Vector2f(0.5f, 0.5f));
}

TEST(RenderTest, DistortedCameraUsesItsOwnModel) {
  // OPENCV camera with strong barrel distortion: at 1 spp the pixel (x, y) is covered exactly
  // when the ray CamFromImg(x + 0.5, y + 0.5) hits the triangle.
  Camera camera;
  camera.model = CameraModel::kOpenCv;
  camera.width = 80;
  camera.height = 60;
  camera.params = {70.0, 72.0, 40.3, 29.7, -0.25, 0.06, 0.001, -0.002};
  const mesh::Mesh mesh = MakeTriangle();
  RenderModel model(mesh);
  RenderOptions options;
  options.samples_per_pixel = 1;
  const Rephoto r = RenderRephoto(model, camera, Pose(), options);
  int inside = 0, differs_from_pinhole = 0;
  for (int y = 0; y < 60; ++y) {
    for (int x = 0; x < 80; ++x) {
      const auto ray = camera.CamFromImg(Eigen::Vector2d(x + 0.5, y + 0.5));
      ASSERT_TRUE(ray.has_value());
      Eigen::Vector3d bary;
      double z, margin;
      const bool hit =
          IntersectClosedForm(mesh, ray->x() / ray->z(), ray->y() / ray->z(), &bary, &z, &margin);
      if (std::abs(margin) < 1e-4) continue;
      ASSERT_EQ(r.color.at(x, y, 3), hit ? 1.0f : 0.0f) << x << "," << y;
      if (hit) {
        ++inside;
        EXPECT_NEAR(r.depth.at(x, y), z, 1e-4 * z);
        EXPECT_NEAR(r.color.at(x, y, 1), bary(1), 1e-4);
      }
      Eigen::Vector3d pin_bary;
      double pin_z, pin_margin;
      const bool pinhole_hit = IntersectClosedForm(
          mesh, (x + 0.5 - 40.3) / 70.0, (y + 0.5 - 29.7) / 72.0, &pin_bary, &pin_z, &pin_margin);
      differs_from_pinhole += hit != pinhole_hit;
    }
  }
  EXPECT_GT(inside, 500);
  EXPECT_GT(differs_from_pinhole, 20);  // the distortion matters for this test
}

// A bumpy sphere of 2 x 24 x 48 triangles at z = 3 with coloured vertices: partly occluded
// triangles, silhouettes and back faces.
mesh::Mesh MakeBumpySphere() {
  mesh::Mesh m;
  const int rows = 24, cols = 48;
  for (int i = 0; i <= rows; ++i) {
    const double theta = M_PI * i / rows;
    for (int j = 0; j < cols; ++j) {
      const double phi = 2 * M_PI * j / cols;
      const double r = 1.0 + 0.1 * std::sin(5 * theta) * std::cos(7 * phi);
      m.positions.emplace_back(r * std::sin(theta) * std::cos(phi),
                               r * std::sin(theta) * std::sin(phi), 3.0 + r * std::cos(theta));
      m.colors.emplace_back(0.5 + 0.5 * std::sin(3 * phi), 0.5 + 0.5 * std::cos(2 * theta),
                            0.5 + 0.5 * std::sin(theta + phi));
    }
  }
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) {
      const uint32_t a = i * cols + j, b = i * cols + (j + 1) % cols;
      const uint32_t c = (i + 1) * cols + j, d = (i + 1) * cols + (j + 1) % cols;
      m.faces.push_back({a, c, b});
      m.faces.push_back({b, c, d});
    }
  }
  return m;
}

// Both packet widths on every instruction-set path this CPU has (core/isa.h; Embree's kernels
// follow the path), against the 8-wide image of the first path: the same bytes.
TEST(RenderTest, PacketWidthsAndIsaPathsGiveTheSameImage) {
  // Odd size: partial tiles of both widths at the right and bottom edges.
  const Camera camera = MakePinhole(53, 39, 30.0, 26.2, 19.7);
  std::vector<Rephoto> first;  // per configuration, on the first path
  for (core::Isa isa : core::SupportedIsas()) {
    core::ScopedIsa scoped(isa);
    RenderModel model(MakeBumpySphere());
    size_t configuration = 0;
    for (int spp : {1, 2, 3, 4, 5, 16}) {
      for (bool backfaces : {true, false}) {
        SCOPED_TRACE(::testing::Message() << "isa " << core::IsaName(isa) << " spp " << spp
                                          << " backfaces " << backfaces);
        RenderOptions options;
        options.samples_per_pixel = spp;
        options.backfaces = backfaces;
        options.packet_width = 8;
        const Rephoto eight = RenderRephoto(model, camera, Pose(), options);
        options.packet_width = 16;
        const Rephoto sixteen = RenderRephoto(model, camera, Pose(), options);
        options.packet_width = 0;
        const Rephoto by_cpu = RenderRephoto(model, camera, Pose(), options);
        double coverage = 0;
        for (int y = 0; y < camera.height; ++y) {
          for (int x = 0; x < camera.width; ++x) coverage += eight.color.at(x, y, 3);
        }
        EXPECT_GT(coverage, 300);  // the sphere covers ~380 pixels (radius ~11 px)
        if (first.size() <= configuration) first.push_back(eight);
        const Rephoto& reference = first[configuration++];
        for (const Rephoto* other : {&eight, &sixteen, &by_cpu}) {
          EXPECT_EQ(std::memcmp(reference.color.data(), other->color.data(),
                                reference.color.size() * sizeof(float)),
                    0);
          EXPECT_EQ(std::memcmp(reference.depth.data(), other->depth.data(),
                                reference.depth.size() * sizeof(float)),
                    0);
        }
      }
    }
  }
}

// Moeller-Trumbore ray-triangle intersection as render.h specifies it (float, these operations
// in this order, no contraction): ray o + t d, hit = (1 - u - v) p0 + u p1 + v p2. False for an
// edge-on triangle.
bool MoellerTrumbore(const Eigen::Vector3f& o, const Eigen::Vector3f& d, const Eigen::Vector3f& p0,
                     const Eigen::Vector3f& p1, const Eigen::Vector3f& p2, float* t, float* u,
                     float* v) {
  const float e1[3] = {p1.x() - p0.x(), p1.y() - p0.y(), p1.z() - p0.z()};
  const float e2[3] = {p2.x() - p0.x(), p2.y() - p0.y(), p2.z() - p0.z()};
  const float s[3] = {o.x() - p0.x(), o.y() - p0.y(), o.z() - p0.z()};
  const float p[3] = {d.y() * e2[2] - d.z() * e2[1], d.z() * e2[0] - d.x() * e2[2],
                      d.x() * e2[1] - d.y() * e2[0]};
  const float q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2],
                      s[0] * e1[1] - s[1] * e1[0]};
  const float det = (e1[0] * p[0] + e1[1] * p[1]) + e1[2] * p[2];
  if (det == 0.0f) return false;
  *u = ((s[0] * p[0] + s[1] * p[1]) + s[2] * p[2]) / det;
  *v = ((d.x() * q[0] + d.y() * q[1]) + d.z() * q[2]) / det;
  *t = ((e2[0] * q[0] + e2[1] * q[1]) + e2[2] * q[2]) / det;
  return true;
}

// The packet tile loop (vectorized, compiled per ISA path) against a plain per-sample reference:
// for every pixel and sample, SampleOffset, CameraRays::Ray, the world direction, one
// rtcIntersect1 for the triangle, Moeller-Trumbore for (t, u, v) and the barycentric colour,
// summed in sample order. Rotated pose, pinhole and distorted cameras, 1 to 16 samples; on every
// ISA path this CPU has (core/isa.h).

TEST(RenderTest, TileLoopMatchesPerSampleReference) {
  for (core::Isa isa : core::SupportedIsas()) {
    SCOPED_TRACE(::testing::Message() << "isa " << core::IsaName(isa));
    core::ScopedIsa scoped(isa);
    RenderModel model(MakeBumpySphere());
    const mesh::Mesh& mesh = model.mesh();
    Camera distorted = MakePinhole(45, 37, 28.0, 22.3, 18.9);
    distorted.model = CameraModel::kOpenCv;
    distorted.params = {28.0, 29.0, 22.3, 18.9, -0.2, 0.05, 0.001, -0.002};
    Pose pose;
    pose.rotation =
        Eigen::AngleAxisd(0.2, Eigen::Vector3d(0.3, -0.5, 0.8).normalized()).toRotationMatrix();
    pose.translation = pose.rotation * Eigen::Vector3d(0.2, -0.1, 0.3);
    const Eigen::Matrix3f world_from_cam = pose.rotation.transpose().cast<float>();
    const Eigen::Vector3f origin = pose.Center().cast<float>();
    for (const Camera& camera : {MakePinhole(45, 37, 28.0, 22.3, 18.9), distorted}) {
      const CameraRays rays(camera);
      for (int spp : {1, 3, 4, 16}) {
        SCOPED_TRACE(::testing::Message()
                     << "model " << static_cast<int>(camera.model) << " spp " << spp);
        RenderOptions options;
        options.samples_per_pixel = spp;
        options.seed = 11;
        const Rephoto r = RenderRephoto(model, camera, pose, options);
        int covered = 0;
        for (int y = 0; y < camera.height; ++y) {
          for (int x = 0; x < camera.width; ++x) {
            Eigen::Vector3f sum = Eigen::Vector3f::Zero();
            float nearest = std::numeric_limits<float>::infinity();
            int hits = 0;
            for (int s = 0; s < spp; ++s) {
              const Eigen::Vector2f offset = SampleOffset(x, y, s, options);
              float xn, yn;
              if (!rays.Ray(x + offset.x(), y + offset.y(), &xn, &yn)) continue;
              const Eigen::Vector3f d =
                  world_from_cam.col(0) * xn + world_from_cam.col(1) * yn + world_from_cam.col(2);
              RTCIntersectContext context;
              rtcInitIntersectContext(&context);
              RTCRayHit ray{};
              ray.ray.org_x = origin.x();
              ray.ray.org_y = origin.y();
              ray.ray.org_z = origin.z();
              ray.ray.dir_x = d.x();
              ray.ray.dir_y = d.y();
              ray.ray.dir_z = d.z();
              ray.ray.tfar = std::numeric_limits<float>::infinity();
              ray.ray.mask = 0xFFFFFFFFu;
              ray.hit.geomID = RTC_INVALID_GEOMETRY_ID;
              rtcIntersect1(model.scene(), &context, &ray);
              if (ray.hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
              const mesh::Triangle& f = mesh.faces[ray.hit.primID];
              // Embree finds the triangle; (t, u, v) are render.h's own Moeller-Trumbore values.
              float t, u, v;
              ASSERT_TRUE(MoellerTrumbore(origin, d, mesh.positions[f[0]], mesh.positions[f[1]],
                                          mesh.positions[f[2]], &t, &u, &v));
              EXPECT_NEAR(t, ray.ray.tfar, 1e-5f * t);
              EXPECT_NEAR(u, ray.hit.u, 1e-4f);
              EXPECT_NEAR(v, ray.hit.v, 1e-4f);
              sum +=
                  (1 - u - v) * mesh.colors[f[0]] + u * mesh.colors[f[1]] + v * mesh.colors[f[2]];
              nearest = std::min(nearest, t);
              ++hits;
            }
            ASSERT_EQ(r.color.at(x, y, 3), static_cast<float>(hits) / spp) << x << "," << y;
            if (hits == 0) {
              EXPECT_TRUE(std::isnan(r.depth.at(x, y)));
              continue;
            }
            ++covered;
            for (int c = 0; c < 3; ++c) {
              EXPECT_EQ(r.color.at(x, y, c), sum[c] * (1.0f / hits)) << x << "," << y << "," << c;
            }
            EXPECT_EQ(r.depth.at(x, y), nearest) << x << "," << y;
          }
        }
        EXPECT_GT(covered, 200);  // the sphere covers about 280 of 1665 pixels
      }
    }
  }
}

TEST(RenderTest, RejectsBadInput) {
  RenderModel model(MakeTriangle());
  Camera camera = MakePinhole(40, 30, 0.0, 20, 15);
  EXPECT_THROW(RenderRephoto(model, camera, Pose()), Error);
  camera = MakePinhole(40, 30, 30.0, 20, 15);
  RenderOptions options;
  options.samples_per_pixel = 0;
  EXPECT_THROW(RenderRephoto(model, camera, Pose(), options), Error);
  options.samples_per_pixel = 1;
  options.packet_width = 4;
  EXPECT_THROW(RenderRephoto(model, camera, Pose(), options), Error);
  mesh::Mesh bad = MakeTriangle();
  bad.faces[0][2] = 5;
  try {
    RenderModel broken(bad, {}, "bad.ply");
    ADD_FAILURE();
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("bad.ply: face 0: vertex index 5"));
  }
}

// Overlapping coplanar discs (a flat ground seen as points) are hit at exactly the same t: the
// disc whose centre is nearest to the hit point shows (a Voronoi partition of the plane), in
// whatever order the points are stored, on every ISA path and packet width.
TEST(RenderTest, CoplanarDiscsShowTheNearestCentre) {
  const Camera camera = MakePinhole(64, 48, 60.0, 32, 24);
  mesh::Mesh grid;
  for (int j = 0; j < 7; ++j) {
    for (int i = 0; i < 9; ++i) {
      grid.positions.emplace_back(-0.4f + 0.1f * i, -0.3f + 0.1f * j, 2.0f);
      grid.colors.emplace_back(i / 8.0f, j / 6.0f, 0.5f);
      grid.normals.emplace_back(0.0f, 0.0f, -1.0f);
      grid.radii.push_back(0.12f);  // overlapping neighbours
    }
  }
  mesh::Mesh reversed = grid;
  std::reverse(reversed.positions.begin(), reversed.positions.end());
  std::reverse(reversed.colors.begin(), reversed.colors.end());
  std::vector<Rephoto> renders;
  for (core::Isa isa : core::SupportedIsas()) {
    core::ScopedIsa scoped(isa);
    for (const mesh::Mesh* m : {&grid, &reversed}) {
      RenderModel model(*m);
      for (int width : {8, 16}) {
        RenderOptions options;
        options.samples_per_pixel = 1;
        options.packet_width = width;
        renders.push_back(RenderRephoto(model, camera, Pose(), options));
      }
    }
  }
  int checked = 0;
  for (int y = 0; y < 48; ++y) {
    for (int x = 0; x < 64; ++x) {
      // The hit point on z = 2 and the nearest centre (closed form), unless two tie closely.
      const Eigen::Vector2d p(2.0 * (x + 0.5 - 32) / 60.0, 2.0 * (y + 0.5 - 24) / 60.0);
      double best = INFINITY, second = INFINITY;
      int nearest = -1;
      for (size_t k = 0; k < grid.positions.size(); ++k) {
        const double dist = (p - grid.positions[k].head<2>().cast<double>()).norm();
        if (dist < best) {
          second = best;
          best = dist;
          nearest = static_cast<int>(k);
        } else if (dist < second) {
          second = dist;
        }
      }
      if (best > 0.119 || second - best < 1e-4) continue;
      ++checked;
      for (const Rephoto& r : renders) {
        ASSERT_EQ(r.color.at(x, y, 3), 1.0f) << x << "," << y;
        EXPECT_EQ(r.color.at(x, y, 0), grid.colors[nearest].x()) << x << "," << y;
        EXPECT_EQ(r.color.at(x, y, 1), grid.colors[nearest].y()) << x << "," << y;
      }
    }
  }
  EXPECT_GT(checked, 300);  // the grid covers about 27 x 21 pixels
}

TEST(RenderTest, PointCloudDiscs) {
  const Camera camera = MakePinhole(60, 40, 50.0, 30, 20);
  mesh::Mesh points;
  points.positions = {Eigen::Vector3f(0.1f, -0.05f, 2.0f), Eigen::Vector3f(-0.4f, 0.1f, 3.0f)};
  points.colors = {Eigen::Vector3f(1, 0.5f, 0), Eigen::Vector3f(0, 0.25f, 1)};
  points.radii = {0.15f, 0.2f};
  for (bool oriented : {false, true}) {
    mesh::Mesh m = points;
    if (oriented) m.normals = {Eigen::Vector3f(0, 0, -1), Eigen::Vector3f(0, 0, 1)};
    RenderModel model(m);
    ASSERT_EQ(model.representation(), Representation::kPointCloud);
    RenderOptions options;
    options.samples_per_pixel = 1;
    const Rephoto r = RenderRephoto(model, camera, Pose(), options);
    int covered = 0;
    for (int y = 0; y < 40; ++y) {
      for (int x = 0; x < 60; ++x) {
        const Eigen::Vector3d d((x + 0.5 - 30) / 50.0, (y + 0.5 - 20) / 50.0, 1);
        // Closed form per disc: the parameter t (= depth) and the distance from the centre.
        double best_t = INFINITY;
        int best = -1;
        bool ambiguous = false;
        for (int k = 0; k < 2; ++k) {
          const Eigen::Vector3d c = m.positions[k].cast<double>();
          const double t = oriented ? c.z() : c.dot(d) / d.squaredNorm();
          const double distance = (t * d - c).norm();
          ambiguous |= std::abs(distance - m.radii[k]) < 1e-4;
          if (distance <= m.radii[k] && t < best_t) {
            best_t = t;
            best = k;
          }
        }
        if (ambiguous) continue;
        ASSERT_EQ(r.color.at(x, y, 3), best >= 0 ? 1.0f : 0.0f) << x << "," << y;
        if (best < 0) continue;
        ++covered;
        EXPECT_NEAR(r.depth.at(x, y), best_t, 1e-5);
        EXPECT_EQ(r.color.at(x, y, 2), m.colors[best].z());
      }
    }
    EXPECT_GT(covered, 60);  // discs of about 3.5 px radius
  }
}

TEST(RenderTest, KthNeighborDistancesOnAGrid) {
  // Unit grid: the neighbours of an interior point are at 1 (4x), sqrt(2) (4x), 2 (4x).
  std::vector<Eigen::Vector3f> grid;
  for (int y = 0; y < 20; ++y) {
    for (int x = 0; x < 20; ++x) grid.emplace_back(x, y, 0.5f);
  }
  const auto d4 = KthNeighborDistances(grid, 4);
  const auto d6 = KthNeighborDistances(grid, 6);
  const auto d9 = KthNeighborDistances(grid, 9);
  const int interior = 10 * 20 + 10;
  EXPECT_FLOAT_EQ(d4[interior], 1.0f);
  EXPECT_FLOAT_EQ(d6[interior], std::sqrt(2.0f));
  EXPECT_FLOAT_EQ(d9[interior], 2.0f);
  EXPECT_FLOAT_EQ(d4[0], 2.0f);  // corner: 1, 1, sqrt2, 2
  // Against brute force on random points.
  auto rng = testing::MakeRng();
  std::uniform_real_distribution<float> uniform(0, 1);
  std::vector<Eigen::Vector3f> random;
  for (int i = 0; i < 500; ++i) random.emplace_back(uniform(rng), uniform(rng), uniform(rng));
  const auto fast = KthNeighborDistances(random, 6);
  for (int i = 0; i < 500; i += 7) {
    std::vector<float> all;
    for (int j = 0; j < 500; ++j) {
      if (j != i) all.push_back((random[i] - random[j]).norm());
    }
    std::sort(all.begin(), all.end());
    EXPECT_FLOAT_EQ(fast[i], all[5]);
  }
}

// A quad filling the view exactly (pinhole, z = 1) with uv = pixel position / image size.
mesh::Mesh MakeTexturedQuad(const std::filesystem::path& texture, int width, int height, double f) {
  mesh::Mesh mesh;
  const float hx = static_cast<float>(width / 2.0 / f), hy = static_cast<float>(height / 2.0 / f);
  mesh.positions = {Eigen::Vector3f(-hx, -hy, 1), Eigen::Vector3f(hx, -hy, 1),
                    Eigen::Vector3f(hx, hy, 1), Eigen::Vector3f(-hx, hy, 1)};
  // Image top (y = -hy) is v = 1 (OpenGL convention).
  mesh.vertex_texcoords = {Eigen::Vector2f(0, 1), Eigen::Vector2f(1, 1), Eigen::Vector2f(1, 0),
                           Eigen::Vector2f(0, 0)};
  mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  mesh.materials.push_back({"tex", Eigen::Vector3f::Ones(), texture});
  return mesh;
}

TEST(RenderTest, TexturedMeshMagnifiedAndMinified) {
  const auto dir = testing::MakeTempDir();
  // 4 x 4 texture with distinct colours.
  Image small(4, 4, 3);
  for (int y = 0; y < 4; ++y) {
    for (int x = 0; x < 4; ++x) {
      small.at(x, y, 0) = (x * 60 + 10) / 255.0f;
      small.at(x, y, 1) = (y * 60 + 20) / 255.0f;
      small.at(x, y, 2) = ((x + y) * 25) / 255.0f;
    }
  }
  io::WritePng(dir / "small.png", small);
  const Camera camera = MakePinhole(64, 64, 64.0, 32, 32);
  {
    RenderModel model(MakeTexturedQuad(dir / "small.png", 64, 64, 64.0));
    ASSERT_EQ(model.representation(), Representation::kTexturedMesh);
    RenderOptions options;
    options.samples_per_pixel = 1;
    const Rephoto r = RenderRephoto(model, camera, Pose(), options);
    // Each texel spans 16 x 16 pixels. Pixel (16 tx + 8, 16 ty + 8) has its centre 1/32 texel
    // right of and below the texel centre: bilinear weights 31/32 and 1/32, wrapping (repeat).
    for (int ty = 0; ty < 4; ++ty) {
      for (int tx = 0; tx < 4; ++tx) {
        const int x = tx * 16 + 8, y = ty * 16 + 8;
        const int tx1 = (tx + 1) % 4, ty1 = (ty + 1) % 4;
        const float a = 31.0f / 32, b = 1.0f / 32;
        for (int c = 0; c < 3; ++c) {
          const float expected = a * a * small.at(tx, ty, c) + b * a * small.at(tx1, ty, c) +
                                 a * b * small.at(tx, ty1, c) + b * b * small.at(tx1, ty1, c);
          EXPECT_NEAR(r.color.at(x, y, c), expected, 1e-4) << tx << "," << ty << "," << c;
        }
        EXPECT_EQ(r.color.at(x, y, 3), 1.0f);
      }
    }
  }
  // 512 x 512 one-texel checkerboard shown on 64 x 64 pixels: 8 x 8 texels per pixel. With
  // mipmapping every pixel is the mean grey; point sampling would give 0/1 noise.
  Image checker(512, 512, 3);
  for (int y = 0; y < 512; ++y) {
    for (int x = 0; x < 512; ++x) {
      for (int c = 0; c < 3; ++c) checker.at(x, y, c) = static_cast<float>((x + y) % 2);
    }
  }
  io::WritePng(dir / "checker.png", checker);
  RenderModel model(MakeTexturedQuad(dir / "checker.png", 64, 64, 64.0));
  for (int spp : {1, 4}) {
    RenderOptions options;
    options.samples_per_pixel = spp;
    const Rephoto r = RenderRephoto(model, camera, Pose(), options);
    double sum = 0, sum2 = 0;
    for (int y = 0; y < 64; ++y) {
      for (int x = 0; x < 64; ++x) {
        sum += r.color.at(x, y, 0);
        sum2 += r.color.at(x, y, 0) * r.color.at(x, y, 0);
      }
    }
    const double mean = sum / 4096, deviation = std::sqrt(std::max(0.0, sum2 / 4096 - mean * mean));
    EXPECT_NEAR(mean, 0.5, 0.01) << spp;
    EXPECT_LT(deviation, 0.01) << spp;
  }
  // A missing texture is an error naming the file.
  try {
    RenderModel missing(MakeTexturedQuad(dir / "missing.png", 64, 64, 64.0));
    ADD_FAILURE();
  } catch (const Error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("missing.png"));
  }
}

}  // namespace
}  // namespace rephoto::render

namespace rephoto::render {
namespace {

// A smooth procedural texture on the plane z = 1 (x, y in [-1, 1]), rendered with an OPENCV
// camera and then undistorted (each pinhole pixel centre mapped through ImgFromCam and sampled
// bilinearly) agrees with the pinhole rendering away from the border.
TEST(RenderTest, DistortedRenderingUndistortsToThePinholeRendering) {
  const auto dir = testing::MakeTempDir();
  Image texture(64, 64, 3);
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      texture.at(x, y, 0) = 0.5f + 0.4f * std::sin(2 * 3.14159265f * x / 32);
      texture.at(x, y, 1) = 0.5f + 0.4f * std::cos(2 * 3.14159265f * y / 32);
      texture.at(x, y, 2) = 0.5f + 0.3f * std::sin(2 * 3.14159265f * (x + y) / 64);
    }
  }
  io::WritePng(dir / "smooth.png", texture);
  mesh::Mesh plane;
  plane.positions = {Eigen::Vector3f(-1, -1, 1), Eigen::Vector3f(1, -1, 1),
                     Eigen::Vector3f(1, 1, 1), Eigen::Vector3f(-1, 1, 1)};
  plane.faces = {{0, 1, 2}, {0, 2, 3}};
  // Stored as OpenMVS does: wedge texture coordinates and a TextureFile, through a PLY file.
  const Eigen::Vector2f uv[4] = {{0, 1}, {1, 1}, {1, 0}, {0, 0}};
  for (const mesh::Triangle& t : plane.faces) {
    for (uint32_t i : t) plane.wedge_texcoords.push_back(uv[i]);
  }
  plane.materials.push_back({"smooth.png", Eigen::Vector3f::Ones(), "smooth.png"});
  mesh::WritePly(dir / "plane.ply", plane);
  RenderModel model(mesh::ReadPly(dir / "plane.ply"));
  ASSERT_EQ(model.representation(), Representation::kTexturedMesh);

  Camera pinhole = MakePinhole(96, 72, 60.0, 48.0, 36.0);
  Camera distorted;
  distorted.model = CameraModel::kOpenCv;
  distorted.width = 96;
  distorted.height = 72;
  distorted.params = {60.0, 60.0, 48.0, 36.0, -0.05, 0.01, 0.002, -0.001};
  RenderOptions options;
  options.samples_per_pixel = 1;
  const Rephoto reference = RenderRephoto(model, pinhole, Pose(), options);
  const Rephoto warped = RenderRephoto(model, distorted, Pose(), options);
  double sum = 0, worst = 0;
  int count = 0, moved = 0;
  for (int y = 4; y < 68; ++y) {
    for (int x = 4; x < 92; ++x) {
      const Eigen::Vector3d ray((x + 0.5 - 48.0) / 60.0, (y + 0.5 - 36.0) / 60.0, 1.0);
      const auto pixel = distorted.ImgFromCam(ray);
      ASSERT_TRUE(pixel.has_value());
      moved += (*pixel - Eigen::Vector2d(x + 0.5, y + 0.5)).norm() > 1.0;
      const double px = pixel->x() - 0.5, py = pixel->y() - 0.5;
      const int x0 = static_cast<int>(std::floor(px)), y0 = static_cast<int>(std::floor(py));
      if (x0 < 0 || y0 < 0 || x0 + 1 >= 96 || y0 + 1 >= 72) continue;
      const double ax = px - x0, ay = py - y0;
      for (int c = 0; c < 3; ++c) {
        const double top =
            (1 - ax) * warped.color.at(x0, y0, c) + ax * warped.color.at(x0 + 1, y0, c);
        const double bottom =
            (1 - ax) * warped.color.at(x0, y0 + 1, c) + ax * warped.color.at(x0 + 1, y0 + 1, c);
        const double difference =
            std::abs((1 - ay) * top + ay * bottom - reference.color.at(x, y, c));
        sum += difference;
        worst = std::max(worst, difference);
        ++count;
      }
    }
  }
  std::printf(
      "undistorted vs pinhole: mean |diff| %.5f, worst %.5f over %d values; %d pixels "
      "moved by more than 1 px\n",
      sum / count, worst, count, moved);
  EXPECT_GT(moved, 500);  // the distortion is not negligible
  EXPECT_LT(sum / count, 0.001);
  EXPECT_LT(worst, 0.01);
}

}  // namespace
}  // namespace rephoto::render

namespace rephoto::render {
namespace {

TEST(RenderTest, DensityRadiiAreCappedForOutliers) {
  mesh::Mesh cloud;
  for (int y = 0; y < 10; ++y) {
    for (int x = 0; x < 10; ++x) cloud.positions.emplace_back(0.1f * x, 0.1f * y, 5.0f);
  }
  cloud.positions.emplace_back(0.0f, 0.0f, 1.0f);  // a stray point 4 units in front
  ModelOptions options;
  const RenderModel model(cloud, options);
  const auto& radii = model.point_radii();
  ASSERT_EQ(radii.size(), 101u);
  // Interior grid points: the 6th neighbour is at 0.1 * sqrt(2); the median over the grid.
  EXPECT_FLOAT_EQ(radii[55], 0.1f * std::sqrt(2.0f));
  EXPECT_FLOAT_EQ(radii[100], 3.0f * 0.1f * std::sqrt(2.0f));  // capped (uncapped: about 4)
  options.point_radius = 0.02f;
  const RenderModel fixed(cloud, options);
  EXPECT_EQ(fixed.point_radii()[100], 0.02f);
}

}  // namespace
}  // namespace rephoto::render
