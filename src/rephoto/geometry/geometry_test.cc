// Geometric accuracy/completeness against closed-form answers on spheres, hemispheres and
// planes. Tolerances: the tessellation error s (the sagitta, TessellationError: how far the
// faces lie inside their sphere; every distance below moves by at most s_model + s_reference)
// plus the sampling noise of an area fraction p from N stratified samples, at most
// sqrt(p (1 - p) / N) <= 0.5 / sqrt(N) (0.0011 at N = 200000; we allow 4 sigma).
#include "rephoto/geometry/geometry.h"

#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>

#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/parallel.h"
#include "rephoto/geometry/sampling.h"
#include "rephoto/geometry/shapes.h"
#include "rephoto/geometry/surface_distance.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/testing/testing.h"

namespace rephoto::geometry {
namespace {

constexpr size_t kSamples = 200'000;
const double kNoise = 4 * 0.5 / std::sqrt(static_cast<double>(kSamples));  // 4 sigma, 0.0045

GeometryOptions Options(std::vector<double> tolerances, double fraction = 0.9) {
  GeometryOptions options;
  options.tolerances = std::move(tolerances);
  options.accuracy_fraction = fraction;
  options.samples = kSamples;
  options.seed = 7;
  return options;
}

// Brute force: the minimum over a dense barycentric grid (an upper bound within h of the truth).
double GridDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                    const Eigen::Vector3d& c, int n) {
  double best = std::numeric_limits<double>::infinity();
  for (int i = 0; i <= n; ++i) {
    for (int j = 0; i + j <= n; ++j) {
      const double u = double(i) / n, v = double(j) / n;
      best = std::min(best, (p - (a + u * (b - a) + v * (c - a))).norm());
    }
  }
  return best;
}

TEST(GeometryTest, PointTriangleDistanceMatchesDenseGrid) {
  std::mt19937_64 rng = testing::MakeRng();
  std::uniform_real_distribution<double> uniform(-1, 1);
  auto random_point = [&] { return Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng)); };
  for (int trial = 0; trial < 300; ++trial) {
    const Eigen::Vector3d a = random_point(), b = random_point(), c = random_point(),
                          p = 2 * random_point();
    Eigen::Vector3d closest;
    const double d = std::sqrt(PointTriangleDistanceSquared(p, a, b, c, &closest));
    const double grid = GridDistance(p, a, b, c, 400);
    // The grid point is never closer than the exact answer, and within a grid cell of it.
    EXPECT_LE(d, grid + 1e-12);
    EXPECT_NEAR(d, grid, 0.02);
    EXPECT_NEAR((closest - p).norm(), d, 1e-12);
  }
  // Exact cases: above the interior, beyond a vertex, beyond an edge, a degenerate triangle.
  const Eigen::Vector3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  EXPECT_DOUBLE_EQ(PointTriangleDistanceSquared({0.2, 0.2, 3}, a, b, c), 9.0);
  EXPECT_DOUBLE_EQ(PointTriangleDistanceSquared({-1, -1, 0}, a, b, c), 2.0);
  EXPECT_DOUBLE_EQ(PointTriangleDistanceSquared({0.5, -2, 0}, a, b, c), 4.0);
  EXPECT_DOUBLE_EQ(PointTriangleDistanceSquared({1, 1, 0}, a, b, c), 0.5);
  EXPECT_DOUBLE_EQ(PointTriangleDistanceSquared({0.5, 1, 0}, a, b, Eigen::Vector3d(2, 0, 0)), 1.0);
}

TEST(GeometryTest, SurfaceDistanceEqualsBruteForce) {
  std::mt19937_64 rng = testing::MakeRng();
  std::uniform_real_distribution<double> uniform(-1.5, 1.5);
  const mesh::Mesh sphere = MakeIcosphere(1.0, 2);
  const SurfaceDistance distance(sphere, "sphere");
  std::vector<Eigen::Vector3f> points;
  for (int i = 0; i < 500; ++i) {
    points.emplace_back(uniform(rng), uniform(rng), uniform(rng));
  }
  const std::vector<float> fast = distance.Distances(points);
  for (size_t i = 0; i < points.size(); ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (const mesh::Triangle& f : sphere.faces) {
      best = std::min(best, PointTriangleDistanceSquared(points[i].cast<double>(),
                                                         sphere.positions[f[0]].cast<double>(),
                                                         sphere.positions[f[1]].cast<double>(),
                                                         sphere.positions[f[2]].cast<double>()));
    }
    EXPECT_FLOAT_EQ(fast[i], static_cast<float>(std::sqrt(best))) << i;
  }
  // Point clouds: the nearest point.
  mesh::Mesh cloud;
  cloud.positions = sphere.positions;
  const SurfaceDistance nearest(cloud, "cloud");
  const std::vector<float> to_points = nearest.Distances(points);
  for (size_t i = 0; i < points.size(); ++i) {
    float best = std::numeric_limits<float>::infinity();
    for (const Eigen::Vector3f& q : cloud.positions) best = std::min(best, (q - points[i]).norm());
    EXPECT_FLOAT_EQ(to_points[i], best) << i;
  }
}

TEST(GeometryTest, SamplesAreAreaUniformAndSeeded) {
  // Two triangles of areas 1/2 and 3/2 (the second twice as wide): 1/4 and 3/4 of the samples.
  mesh::Mesh mesh;
  mesh.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {4, 0, 0}, {1, 1, 0}};
  mesh.faces = {{0, 1, 2}, {1, 3, 4}};
  const SurfaceSamples samples = SampleSurface(mesh, 100000, 3);
  size_t first = 0;
  for (uint32_t f : samples.sources) first += f == 0 ? 1 : 0;
  EXPECT_NEAR(first / 100000.0, 0.25, 1e-4);  // stratified: exact up to one sample
  EXPECT_EQ(SampleSurface(mesh, 1000, 3).positions, SampleSurface(mesh, 1000, 3).positions);
  EXPECT_NE(SampleSurface(mesh, 1000, 3).positions, SampleSurface(mesh, 1000, 4).positions);
  // On a sphere, z is uniform in [-1, 1] (Archimedes): 1/4 of the area has z > 0.5.
  const SurfaceSamples on_sphere = SampleSurface(MakeIcosphere(1, 5), kSamples, 1);
  size_t above = 0;
  for (const Eigen::Vector3f& p : on_sphere.positions) above += p.z() > 0.5f ? 1 : 0;
  EXPECT_NEAR(double(above) / kSamples, 0.25, kNoise);
  EXPECT_THROW(SampleSurface(mesh, 0, 1), Error);
}

// Concentric spheres, model radius 1, reference radius 1.02: every model point is 0.02 from
// the reference and every reference point 0.02 from the model. So accuracy = 0.02 for any
// fraction; completeness = precision = recall = F = 1 for t >= 0.02 and 0 below.
TEST(GeometryTest, ConcentricSpheres) {
  const mesh::Mesh model = MakeIcosphere(1.0, 6);
  const mesh::Mesh reference = MakeIcosphere(1.02, 5);
  const double s = TessellationError(model, 1.0, Eigen::Vector3d::Zero()) +
                   TessellationError(reference, 1.02, Eigen::Vector3d::Zero());
  ASSERT_LT(s, 0.0005);
  for (double fraction : {0.5, 0.9, 1.0}) {
    const GeometryResult r =
        EvaluateGeometry(model, reference, Options({0.01, 0.0195, 0.0205, 0.03}, fraction));
    EXPECT_NEAR(r.accuracy, 0.02, s) << fraction;
    const std::vector<double> expected = {0, 0, 1, 1};
    for (size_t i = 0; i < expected.size(); ++i) {
      EXPECT_EQ(r.tolerances[i].completeness, expected[i]) << r.tolerances[i].tolerance;
      EXPECT_EQ(r.tolerances[i].precision, expected[i]);
      EXPECT_EQ(r.tolerances[i].recall, expected[i]);
      EXPECT_EQ(r.tolerances[i].f_score, expected[i]);
    }
    EXPECT_EQ(r.model_samples, kSamples);
    EXPECT_NEAR(r.model_mean_distance, 0.02, s);
    EXPECT_NEAR(r.reference_area, 4 * M_PI * 1.02 * 1.02, 0.01);
  }
}

// Unit spheres whose centres are delta apart (delta = 0.1). A point p on one sphere is at
// | |p - c| - 1 | from the other (centre c along x); |p - c|^2 = 1 + delta^2 - 2 delta x and x is
// uniform in [-1, 1] over the area (Archimedes). The distance is <= t for x in
// [(delta^2 - 2t - t^2), (delta^2 + 2t - t^2)] / (2 delta), an interval of length 2t / delta,
// i.e. an area fraction t / delta while the interval lies inside [-1, 1] (t <= 0.09 here).
// So precision = recall = t / delta, and accuracy(fraction f) = f delta.
TEST(GeometryTest, ShiftedSpheres) {
  const double delta = 0.1;
  const mesh::Mesh model = MakeIcosphere(1.0, 6);
  const mesh::Mesh reference = MakeUvSphere(1.0, 256, 512, {delta, 0, 0});
  const double s = TessellationError(model, 1.0, Eigen::Vector3d::Zero()) +
                   TessellationError(reference, 1.0, Eigen::Vector3d(delta, 0, 0));
  const GeometryResult r = EvaluateGeometry(model, reference, Options({0.01, 0.02, 0.05}, 0.9));
  // A distance error e moves a fraction by e / delta.
  const double fraction_tolerance = kNoise + s / delta;
  for (const ToleranceResult& t : r.tolerances) {
    EXPECT_NEAR(t.precision, t.tolerance / delta, fraction_tolerance) << t.tolerance;
    EXPECT_NEAR(t.recall, t.tolerance / delta, fraction_tolerance) << t.tolerance;
    EXPECT_NEAR(t.f_score, t.tolerance / delta, fraction_tolerance) << t.tolerance;
  }
  EXPECT_NEAR(r.accuracy, 0.9 * delta, kNoise * delta + s);
  const GeometryResult median = EvaluateGeometry(model, reference, Options({0.01}, 0.5));
  EXPECT_NEAR(median.accuracy, 0.5 * delta, kNoise * delta + s);
}

// Model: the upper unit hemisphere (z >= 0); reference: the unit sphere. Every model point lies
// on the reference: accuracy ~ 0, precision 1. A reference point at height z = -h below the rim
// is nearest to the rim point of its azimuth, at the chord 2 sin(phi / 2) with sin(phi) = h; it
// is within t for phi <= 2 asin(t / 2), i.e. h <= sin(2 asin(t / 2)) = t sqrt(1 - t^2 / 4).
// Area is uniform in z, so completeness(t) = recall(t) = 0.5 + 0.5 t sqrt(1 - t^2 / 4), and
// F = 2 R / (1 + R).
TEST(GeometryTest, HemisphereAgainstSphere) {
  const mesh::Mesh model = MakeUvHemisphere(1.0, 128, 512);
  const mesh::Mesh reference = MakeIcosphere(1.0, 6);
  const double s = TessellationError(model, 1.0, Eigen::Vector3d::Zero()) +
                   TessellationError(reference, 1.0, Eigen::Vector3d::Zero());
  ASSERT_LT(s, 0.001);
  const GeometryResult r = EvaluateGeometry(model, reference, Options({0.002, 0.01, 0.1, 0.5}));
  EXPECT_LE(r.accuracy, s);
  EXPECT_NEAR(r.model_area, 2 * M_PI, 0.01);
  for (const ToleranceResult& t : r.tolerances) {
    const double x = t.tolerance;
    const double expected = 0.5 + 0.5 * x * std::sqrt(1 - x * x / 4);
    EXPECT_EQ(t.precision, 1.0) << x;
    EXPECT_NEAR(t.completeness, expected, kNoise + s) << x;
    EXPECT_EQ(t.recall, t.completeness);
    EXPECT_NEAR(t.f_score, 2 * expected / (1 + expected), kNoise + s) << x;
  }
  // The other way round: the sphere as the model is half outside the hemisphere.
  const GeometryResult reverse = EvaluateGeometry(reference, model, Options({0.1}, 0.5));
  EXPECT_NEAR(reverse.tolerances[0].precision, 0.5 + 0.05 * std::sqrt(1 - 0.0025), kNoise + s);
  EXPECT_EQ(reverse.tolerances[0].recall, 1.0);
  // Accuracy at 0.5: the median distance lies right at the rim band's start (about 0).
  EXPECT_LE(reverse.accuracy, 0.01);
}

// Unit squares, the reference shifted by 0.5 along x. A model point at x < 0.5 is 0.5 - x from
// the reference, one at x >= 0.5 lies on it: precision(t) = 0.5 + t for t <= 0.5; by symmetry
// recall(t) = 0.5 + t; accuracy(0.9) = 0.4. No tessellation error (planes are exact); the
// samples are uniform within each face, hence the sampling noise.
TEST(GeometryTest, OverlappingSquares) {
  const mesh::Mesh model = MakeRectangle(0, 0, 1, 1, 0);
  const mesh::Mesh reference = MakeRectangle(0.5, 0, 1.5, 1, 0);
  const GeometryResult r = EvaluateGeometry(model, reference, Options({0.1, 0.25}, 0.9));
  for (const ToleranceResult& t : r.tolerances) {
    EXPECT_NEAR(t.precision, 0.5 + t.tolerance, kNoise) << t.tolerance;
    EXPECT_NEAR(t.recall, 0.5 + t.tolerance, kNoise) << t.tolerance;
  }
  EXPECT_NEAR(r.accuracy, 0.4, kNoise);
  // Cropped to the overlap, everything matches.
  GeometryOptions cropped = Options({0.001});
  cropped.crop = {{Eigen::Vector3d(0.5, -1, -1), Eigen::Vector3d(1, 2, 1)}};
  const GeometryResult c = EvaluateGeometry(model, reference, cropped);
  EXPECT_EQ(c.accuracy, 0.0);
  EXPECT_EQ(c.tolerances[0].precision, 1.0);
  EXPECT_EQ(c.tolerances[0].completeness, 1.0);
  EXPECT_NEAR(double(c.model_samples) / kSamples, 0.5, 1e-4);
  // Parallel planes 0.01 apart: every distance 0.01.
  const GeometryResult offset =
      EvaluateGeometry(model, MakeRectangle(0, 0, 1, 1, 0.01), Options({0.005, 0.02}, 0.5));
  EXPECT_NEAR(offset.accuracy, 0.01, 1e-6);
  EXPECT_EQ(offset.tolerances[0].f_score, 0.0);
  EXPECT_EQ(offset.tolerances[1].f_score, 1.0);
}

// The transform is applied to the model first: a sphere at (5, 0, 0) moved back to the origin
// is the concentric case.
TEST(GeometryTest, TransformAppliedToModel) {
  const mesh::Mesh model = MakeIcosphere(1.0, 5, {5, 0, 0});
  GeometryOptions options = Options({0.015, 0.025});
  options.model_from_input(0, 3) = -5;
  const GeometryResult r = EvaluateGeometry(model, MakeIcosphere(1.02, 5), options);
  EXPECT_NEAR(r.accuracy, 0.02, 0.0005);
  EXPECT_EQ(r.tolerances[0].f_score, 0.0);
  EXPECT_EQ(r.tolerances[1].f_score, 1.0);
  options.model_from_input(3, 0) = 1;
  EXPECT_THROW(EvaluateGeometry(model, model, options), UsageError);
}

// Point clouds use nearest-point distances: a cloud against itself is at distance 0; a mesh's
// samples against the cloud of a larger sphere's vertices are at least the radial gap away.
TEST(GeometryTest, PointClouds) {
  const mesh::Mesh sphere = MakeIcosphere(1.0, 4);
  mesh::Mesh cloud;
  cloud.positions = sphere.positions;
  const GeometryResult same = EvaluateGeometry(cloud, cloud, Options({1e-6}));
  EXPECT_EQ(same.accuracy, 0.0);
  EXPECT_EQ(same.tolerances[0].f_score, 1.0);
  EXPECT_TRUE(same.model_is_point_cloud);
  EXPECT_EQ(same.model_samples, cloud.vertex_count());

  mesh::Mesh big_cloud;
  big_cloud.positions = MakeIcosphere(1.02, 5).positions;
  const GeometryResult r = EvaluateGeometry(sphere, big_cloud, Options({0.0195, 0.05}));
  const double s = TessellationError(sphere, 1.0, Eigen::Vector3d::Zero());
  // Reference points to the mesh: the exact 0.02 (+ the model's sagitta).
  EXPECT_NEAR(r.reference_mean_distance, 0.02, s + 1e-5);
  EXPECT_EQ(r.tolerances[0].recall, 0.0);
  EXPECT_EQ(r.tolerances[1].recall, 1.0);
  EXPECT_GE(r.accuracy, 0.02 - 1e-5);
}

TEST(GeometryTest, IndependentOfThreadCount) {
  const mesh::Mesh model = MakeIcosphere(1.0, 4);
  const mesh::Mesh reference = MakeUvSphere(1.01, 40, 80, {0.05, 0, 0});
  GeometryOptions options = Options({0.01, 0.05});
  options.samples = 50000;
  options.vertex_distances = true;
  GeometryResult one, all;
  {
    ThreadLimit limit(1);
    one = EvaluateGeometry(model, reference, options);
  }
  all = EvaluateGeometry(model, reference, options);
  EXPECT_EQ(one.accuracy, all.accuracy);
  EXPECT_EQ(one.tolerances[0].precision, all.tolerances[0].precision);
  EXPECT_EQ(one.model_mean_distance, all.model_mean_distance);
  EXPECT_EQ(one.model_vertex_distances, all.model_vertex_distances);
}

TEST(GeometryTest, WritesJsonCsvAndPly) {
  const std::filesystem::path dir = testing::MakeTempDir();
  const mesh::Mesh model = MakeIcosphere(1.0, 3);
  const mesh::Mesh reference = MakeIcosphere(1.02, 3);
  GeometryOptions options = Options({0.01, 0.03});
  options.samples = 10000;
  options.vertex_distances = true;
  const GeometryResult r = EvaluateGeometry(model, reference, options);
  WriteGeometryJson(r, options, "model.ply", "gt.ply", dir / "geometry.json");
  WriteGeometryCsv(r, dir / "geometry.csv");
  WriteDistancePly(model, r.model_vertex_distances, dir / "model.ply");

  const nlohmann::json json = nlohmann::json::parse(ReadFileToString(dir / "geometry.json"));
  EXPECT_TRUE(json["accuracy"].is_number());
  EXPECT_DOUBLE_EQ(json["accuracy"].get<double>(), r.accuracy);
  ASSERT_EQ(json["tolerances"].size(), 2u);
  for (const char* key : {"tolerance", "completeness", "precision", "recall", "f_score"}) {
    EXPECT_TRUE(json["tolerances"][1][key].is_number()) << key;
  }
  EXPECT_EQ(json["tolerances"][1]["f_score"].get<double>(), 1.0);
  const std::string csv = ReadFileToString(dir / "geometry.csv");
  EXPECT_EQ(csv.substr(0, csv.find('\n')),
            "tolerance,completeness,precision,recall,f_score,accuracy,accuracy_fraction");

  const mesh::Mesh ply = mesh::ReadPly(dir / "model.ply");
  ASSERT_EQ(ply.vertex_count(), model.vertex_count());
  EXPECT_EQ(ply.face_count(), model.face_count());
  ASSERT_EQ(ply.colors.size(), model.vertex_count());
  bool found = false;
  for (const mesh::VertexScalar& scalar : ply.scalars) {
    if (scalar.name != "distance") continue;
    found = true;
    EXPECT_EQ(scalar.values, r.model_vertex_distances);
  }
  EXPECT_TRUE(found);
  // Vertices lie on the sphere of radius 1: exactly 0.02 from the reference's vertices' sphere,
  // and at most 0.02 from its (inner) faces.
  for (float d : r.model_vertex_distances) EXPECT_NEAR(d, 0.02, 0.002);
  EXPECT_THROW(WriteDistancePly(model, {1.0f}, dir / "bad.ply"), Error);
}

TEST(GeometryTest, BadInput) {
  EXPECT_THROW(EvaluateGeometry(mesh::Mesh{}, MakeIcosphere(1, 1), Options({0.1})), Error);
  EXPECT_THROW(EvaluateGeometry(MakeIcosphere(1, 1), MakeIcosphere(1, 1), Options({})), UsageError);
  EXPECT_THROW(EvaluateGeometry(MakeIcosphere(1, 1), MakeIcosphere(1, 1), Options({-1.0})),
               UsageError);
  EXPECT_THROW(EvaluateGeometry(MakeIcosphere(1, 1), MakeIcosphere(1, 1), Options({0.1}, 0.0)),
               UsageError);
  mesh::Mesh flat;
  flat.positions = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}};
  flat.faces = {{0, 1, 2}};
  try {
    EvaluateGeometry(flat, MakeIcosphere(1, 1), Options({0.1}), "flat.ply");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("flat.ply"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rephoto::geometry
