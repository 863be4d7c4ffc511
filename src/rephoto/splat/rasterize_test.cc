// The rasterizer against testdata/reference_rasterizer.py (an independent numpy
// re-implementation of graphdeco's forward pass), on the random scenes of
// testdata/make_fixtures.py, which this test runs with python3 + numpy at test time.
#include "rephoto/splat/rasterize.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>

#include "rephoto/core/error.h"
#include "rephoto/core/isa.h"
#include "rephoto/core/parallel.h"
#include "rephoto/splat/gaussians.h"
#include "rephoto/testing/testing.h"

namespace rephoto::splat {
namespace {

namespace fs = std::filesystem;

// A python3 that imports numpy: $REPHOTO_PYTHON, /usr/bin/python3 (Debian's python3-numpy,
// scripts/install-deps.sh), then python3 on PATH. Empty when there is none.
std::string FindPython() {
  std::vector<std::string> candidates;
  if (const char* env = std::getenv("REPHOTO_PYTHON")) candidates.push_back(env);
  candidates.push_back("/usr/bin/python3");
  candidates.push_back("python3");
  for (const std::string& python : candidates) {
    const std::string command = "'" + python + "' -c 'import numpy' >/dev/null 2>&1";
    if (std::system(command.c_str()) == 0) return python;
  }
  return {};
}

class ReferenceFixtures : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const std::string python = FindPython();
    if (python.empty()) {
      error_ =
          "no python3 with numpy found (tried $REPHOTO_PYTHON, /usr/bin/python3, python3): "
          "install python3-numpy (scripts/install-deps.sh) or set REPHOTO_PYTHON";
      return;
    }
    dir_ = new fs::path(fs::temp_directory_path() /
                        ("rephoto_splat_fixtures_" + std::to_string(::getpid())));
    const fs::path script = testing::SourceDir() / "src/rephoto/splat/testdata/make_fixtures.py";
    const std::string command =
        "'" + python + "' '" + script.string() + "' --out '" + dir_->string() + "'";
    if (std::system(command.c_str()) != 0) error_ = "failed: " + command;
  }
  static void TearDownTestSuite() {
    if (dir_ != nullptr) {
      std::error_code ec;
      fs::remove_all(*dir_, ec);
      delete dir_;
      dir_ = nullptr;
    }
  }
  void SetUp() override { ASSERT_TRUE(error_.empty()) << error_; }

  static fs::path Dir() { return *dir_; }

  static inline fs::path* dir_ = nullptr;
  static inline std::string error_;
};

struct FixtureView {
  camera::Camera camera;
  camera::Pose pose;
  GaussianRenderOptions options;
};

FixtureView ReadView(const fs::path& json_path) {
  std::ifstream in(json_path);
  const nlohmann::json j = nlohmann::json::parse(in);
  FixtureView view;
  view.camera.model = camera::CameraModel::kPinhole;
  view.camera.width = j["width"];
  view.camera.height = j["height"];
  view.camera.params = {j["fx"], j["fy"], j["cx"], j["cy"]};
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) view.pose.rotation(r, c) = j["R"][r * 3 + c];
    view.pose.translation[r] = j["t"][r];
  }
  for (int c = 0; c < 3; ++c) view.options.background[c] = j["background"][c];
  view.options.mode = j["antialiased"] ? GaussianMode::kAntialiased : GaussianMode::kClassic;
  return view;
}

std::vector<float> ReadFloats(const fs::path& path, size_t count) {
  std::vector<float> values(count);
  std::ifstream in(path, std::ios::binary);
  in.read(reinterpret_cast<char*>(values.data()), static_cast<std::streamsize>(count * 4));
  EXPECT_TRUE(in.good()) << path;
  return values;
}

struct Agreement {
  double psnr = 0;
  double mean_alpha_error = 0;
  double mean_depth_error = 0;  // relative, where both have a depth
  double max_abs_error = 0;
};

Agreement Compare(const GaussianRendering& rendering, const std::vector<float>& rgba,
                  const std::vector<float>& depth) {
  Agreement a;
  double squared = 0, alpha = 0, depth_sum = 0;
  size_t depth_count = 0;
  const size_t pixels = rendering.color.pixel_count();
  for (size_t i = 0; i < pixels; ++i) {
    for (int c = 0; c < 3; ++c) {
      const double d = rendering.color.data()[i * 4 + c] - rgba[i * 4 + c];
      squared += d * d;
      a.max_abs_error = std::max(a.max_abs_error, std::abs(d));
    }
    alpha += std::abs(rendering.color.data()[i * 4 + 3] - rgba[i * 4 + 3]);
    const float mine = rendering.depth.data()[i];
    if (std::isfinite(mine) && std::isfinite(depth[i])) {
      depth_sum += std::abs(mine - depth[i]) / depth[i];
      ++depth_count;
    }
  }
  const double mse = squared / (3.0 * pixels);
  a.psnr = mse > 0 ? 10 * std::log10(1.0 / mse) : std::numeric_limits<double>::infinity();
  a.mean_alpha_error = alpha / pixels;
  a.mean_depth_error = depth_count ? depth_sum / depth_count : 0;
  return a;
}

TEST_F(ReferenceFixtures, AgreesWithNumpyReference) {
  for (int k = 0; k < 6; ++k) {
    SCOPED_TRACE(k);
    const fs::path base = Dir() / ("scene_" + std::to_string(k));
    const GaussianModel model = ReadGaussians(fs::path(base.string() + ".ply"));
    const FixtureView view = ReadView(base.string() + ".json");
    const GaussianRendering rendering =
        RenderGaussians(model, view.camera, view.pose, view.options);
    const size_t pixels = static_cast<size_t>(view.camera.width) * view.camera.height;
    const Agreement a = Compare(rendering, ReadFloats(base.string() + ".rgba.f32", pixels * 4),
                                ReadFloats(base.string() + ".depth.f32", pixels));
    std::cout << "scene_" << k << " (SH " << model.sh_degree << ", " << model.size()
              << " Gaussians): PSNR " << a.psnr << " dB, mean |dalpha| " << a.mean_alpha_error
              << ", max |dRGB| " << a.max_abs_error << ", mean rel. depth error "
              << a.mean_depth_error << "\n";
    EXPECT_GE(a.psnr, 45.0);
    EXPECT_LE(a.mean_alpha_error, 0.005);
    EXPECT_LE(a.mean_depth_error, 1e-3);
  }
}

TEST_F(ReferenceFixtures, SameResultWithOneThread) {
  const fs::path base = Dir() / "scene_3";
  const GaussianModel model = ReadGaussians(fs::path(base.string() + ".ply"));
  const FixtureView view = ReadView(base.string() + ".json");
  const GaussianRendering all = RenderGaussians(model, view.camera, view.pose, view.options);
  GaussianRendering one;
  {
    ThreadLimit limit(1);
    one = RenderGaussians(model, view.camera, view.pose, view.options);
  }
  ASSERT_EQ(all.color.size(), one.color.size());
  EXPECT_EQ(0, std::memcmp(all.color.data(), one.color.data(), all.color.size() * 4));
}

// The same bytes on every instruction-set path this CPU has (core/isa.h), pinhole and
// distorted cameras (the resampling path).
TEST_F(ReferenceFixtures, SameResultOnEveryIsaPath) {
  const fs::path base = Dir() / "scene_3";
  const GaussianModel model = ReadGaussians(fs::path(base.string() + ".ply"));
  const FixtureView view = ReadView(base.string() + ".json");
  camera::Camera opencv = view.camera;
  opencv.model = camera::CameraModel::kOpenCv;
  opencv.params = {view.camera.params[0],
                   view.camera.params[1],
                   view.camera.params[2],
                   view.camera.params[3],
                   -0.1,
                   0.02,
                   0.001,
                   -0.001};
  for (const camera::Camera& camera : {view.camera, opencv}) {
    std::vector<GaussianRendering> renderings;
    for (core::Isa isa : core::SupportedIsas()) {
      core::ScopedIsa scoped(isa);
      renderings.push_back(RenderGaussians(model, camera, view.pose, view.options));
    }
    for (size_t i = 1; i < renderings.size(); ++i) {
      SCOPED_TRACE(::testing::Message()
                   << "path " << i << ", camera model " << static_cast<int>(camera.model));
      const GaussianRendering& a = renderings[0];
      const GaussianRendering& b = renderings[i];
      ASSERT_EQ(a.color.size(), b.color.size());
      EXPECT_EQ(0, std::memcmp(a.color.data(), b.color.data(), a.color.size() * 4));
      EXPECT_EQ(0, std::memcmp(a.depth.data(), b.depth.data(), a.depth.size() * 4));
    }
  }
}

// The projection takes the Gaussians 8 at a time, one per vector lane, the last group padded
// with copies of its last Gaussian (rasterize.cc ProjectCore8): a Gaussian's result must not
// depend on its lane or on the others in its group. Rotating the model's order moves each
// Gaussian to another lane and group (and some into the padded one); with distinct depths the
// depth order is the same, so the renders must be the same bytes.
TEST_F(ReferenceFixtures, SameResultWhicheverGaussiansAreProjectedTogether) {
  const fs::path base = Dir() / "scene_3";
  GaussianModel model = ReadGaussians(fs::path(base.string() + ".ply"));
  const FixtureView view = ReadView(base.string() + ".json");
  // Three fewer, so that the last group is padded (the fixture holds a multiple of 8).
  ASSERT_GT(model.size(), 16u);
  const size_t kept = model.size() - (model.size() % 8 == 0 ? 3 : 0);
  model.positions.resize(kept);
  model.scales.resize(kept);
  model.rotations.resize(kept);
  model.opacities.resize(kept);
  model.sh.resize(kept * model.ShCoefficients() * 3);
  ASSERT_GT(model.size() % 8, 0u);
  const GaussianRendering expected = RenderGaussians(model, view.camera, view.pose, view.options);
  const size_t n = model.size(), coefficients = model.ShCoefficients() * 3;
  for (size_t shift : {size_t{1}, size_t{5}, n % 8}) {
    GaussianModel rotated = model;
    for (size_t i = 0; i < n; ++i) {
      const size_t from = (i + shift) % n;
      rotated.positions[i] = model.positions[from];
      rotated.scales[i] = model.scales[from];
      rotated.rotations[i] = model.rotations[from];
      rotated.opacities[i] = model.opacities[from];
      std::copy_n(model.sh.begin() + from * coefficients, coefficients,
                  rotated.sh.begin() + i * coefficients);
    }
    for (core::Isa isa : core::SupportedIsas()) {
      core::ScopedIsa scoped(isa);
      SCOPED_TRACE(::testing::Message() << "shift " << shift << ", " << core::IsaName(isa));
      const GaussianRendering r = RenderGaussians(rotated, view.camera, view.pose, view.options);
      ASSERT_EQ(expected.color.size(), r.color.size());
      EXPECT_EQ(0, std::memcmp(expected.color.data(), r.color.data(), r.color.size() * 4));
    }
  }
}

// An OPENCV camera with zero distortion goes through the undistorted-grid path; it must give
// (nearly) the pinhole image: the grid is larger, which only moves the Jacobian clamp.
TEST_F(ReferenceFixtures, DistortionPathMatchesPinholeWithoutDistortion) {
  const fs::path base = Dir() / "scene_1";
  const GaussianModel model = ReadGaussians(fs::path(base.string() + ".ply"));
  const FixtureView view = ReadView(base.string() + ".json");
  camera::Camera opencv = view.camera;
  opencv.model = camera::CameraModel::kOpenCv;
  opencv.params.insert(opencv.params.end(), {0.0, 0.0, 0.0, 0.0});
  const GaussianRendering pinhole = RenderGaussians(model, view.camera, view.pose, view.options);
  const GaussianRendering distorted = RenderGaussians(model, opencv, view.pose, view.options);
  std::vector<float> rgba(pinhole.color.data(), pinhole.color.data() + pinhole.color.size());
  std::vector<float> depth(pinhole.depth.data(), pinhole.depth.data() + pinhole.depth.size());
  const Agreement a = Compare(distorted, rgba, depth);
  EXPECT_GE(a.psnr, 40.0);
  EXPECT_LE(a.mean_alpha_error, 0.01);
}

// Real distortion: the principal point's pixel sees the same Gaussians as the pinhole camera
// (distortion is zero on the optical axis), and barrel distortion (k1 < 0) pulls more of the
// scene into the image.
TEST_F(ReferenceFixtures, DistortedCameraAgreesOnTheAxis) {
  const fs::path base = Dir() / "scene_0";
  const GaussianModel model = ReadGaussians(fs::path(base.string() + ".ply"));
  FixtureView view = ReadView(base.string() + ".json");
  camera::Camera camera = view.camera;
  camera.width = camera.height = 64;
  camera.params = {60, 60, 32, 32};
  camera::Camera opencv = camera;
  opencv.model = camera::CameraModel::kOpenCv;
  opencv.params.insert(opencv.params.end(), {-0.2, 0.0, 0.0, 0.0});
  const GaussianRendering pinhole = RenderGaussians(model, camera, view.pose, view.options);
  const GaussianRendering distorted = RenderGaussians(model, opencv, view.pose, view.options);
  for (int c = 0; c < 4; ++c) {
    EXPECT_NEAR(distorted.color.at(31, 31, c), pinhole.color.at(31, 31, c), 0.02f) << c;
  }
  EXPECT_NE(0, std::memcmp(pinhole.color.data(), distorted.color.data(),
                           pinhole.color.size() * sizeof(float)));
}

// Decoded compressed formats against the PLY they were made from, within the quantisation.
void ExpectSameGaussians(const GaussianModel& original, const GaussianModel& decoded,
                         bool compressed_ply) {
  ASSERT_EQ(original.size(), decoded.size());
  ASSERT_EQ(decoded.sh_degree, compressed_ply ? original.sh_degree : 0);
  const int k_orig = original.ShCoefficients(), k_dec = decoded.ShCoefficients();
  for (size_t chunk = 0; chunk * 256 < original.size(); ++chunk) {
    const size_t begin = chunk * 256, end = std::min(original.size(), begin + 256);
    Eigen::Vector3f lo = original.positions[begin], hi = lo;
    Eigen::Vector3f lo_s = original.scales[begin].array().log(), hi_s = lo_s;
    Eigen::Vector3f lo_c = Eigen::Vector3f::Constant(1e9), hi_c = -lo_c;
    for (size_t g = begin; g < end; ++g) {
      lo = lo.cwiseMin(original.positions[g]);
      hi = hi.cwiseMax(original.positions[g]);
      const Eigen::Vector3f ls = original.scales[g].array().log();
      lo_s = lo_s.cwiseMin(ls);
      hi_s = hi_s.cwiseMax(ls);
      const Eigen::Vector3f c =
          Eigen::Map<const Eigen::Vector3f>(original.sh.data() + g * k_orig * 3) * kShC0;
      lo_c = lo_c.cwiseMin(c);
      hi_c = hi_c.cwiseMax(c);
    }
    for (size_t g = begin; g < end; ++g) {
      SCOPED_TRACE(g);
      for (int i = 0; i < 3; ++i) {
        if (compressed_ply) {
          // Half a step of 11 (x, z) or 10 (y) bits of the chunk's range, plus float rounding.
          const float bits = i == 1 ? 1023.0f : 2047.0f;
          EXPECT_NEAR(decoded.positions[g][i], original.positions[g][i],
                      0.5f * (hi[i] - lo[i]) / bits + 1e-5f);
          EXPECT_NEAR(std::log(decoded.scales[g][i]), std::log(original.scales[g][i]),
                      0.5f * (hi_s[i] - lo_s[i]) / bits + 1e-4f);
        } else {
          EXPECT_NEAR(decoded.positions[g][i], original.positions[g][i], 1e-6f);
          EXPECT_NEAR(decoded.scales[g][i], original.scales[g][i], 1e-6f * original.scales[g][i]);
        }
        // Colour = C0 * f_dc + 0.5; .splat stores it clamped to [0, 1] in 8 bits.
        const float colour_step = compressed_ply ? 0.5f * (hi_c[i] - lo_c[i]) / 255 : 1.0f / 255;
        float colour = original.sh[g * k_orig * 3 + i] * kShC0 + 0.5f;
        if (!compressed_ply) colour = std::clamp(colour, 0.0f, 1.0f);
        EXPECT_NEAR(decoded.sh[g * k_dec * 3 + i] * kShC0 + 0.5f, colour, colour_step + 1e-5f);
      }
      EXPECT_NEAR(decoded.opacities[g], original.opacities[g],
                  compressed_ply ? 0.5f / 255 + 1e-6f : 1.0f / 255);
      // q and -q are the same rotation.
      const float dot = std::abs(decoded.rotations[g].dot(original.rotations[g]));
      EXPECT_GE(dot, compressed_ply ? 0.9999f : 0.999f);
      if (compressed_ply) {
        for (int k = 1; k < k_orig; ++k) {
          for (int c = 0; c < 3; ++c) {
            const float v = original.sh[(g * k_orig + k) * 3 + c];
            if (std::abs(v) < 3.9f) {  // inside the encodable range [-4, 4)
              EXPECT_NEAR(decoded.sh[(g * k_dec + k) * 3 + c], v, 0.5f * 8 / 256 + 1e-5f);
            }
          }
        }
      }
    }
  }
}

TEST_F(ReferenceFixtures, CompressedPlyDecodesToTheSameGaussians) {
  GaussianFormat format;
  const GaussianModel original = ReadGaussians(Dir() / "scene_3.ply");
  const GaussianModel decoded = ReadGaussians(Dir() / "scene_3.compressed.ply", &format);
  EXPECT_EQ(format, GaussianFormat::kCompressedPly);
  ExpectSameGaussians(original, decoded, true);
}

TEST_F(ReferenceFixtures, SplatDecodesToTheSameGaussians) {
  GaussianFormat format;
  const GaussianModel original = ReadGaussians(Dir() / "scene_3.ply");
  const GaussianModel decoded = ReadGaussians(Dir() / "scene_3.splat", &format);
  EXPECT_EQ(format, GaussianFormat::kSplat);
  ExpectSameGaussians(original, decoded, false);
}

// One Gaussian straight ahead: its weight at the centre pixel is its opacity, and over the
// image the weights add up to the alpha channel.
TEST(AccumulateGaussianErrors, WeightsAreTheBlendingWeights) {
  GaussianModel model;
  model.sh_degree = 0;
  model.positions = {Eigen::Vector3f(0, 0, 2), Eigen::Vector3f(0.05f, 0, 3)};
  model.scales = {Eigen::Vector3f::Constant(0.02f), Eigen::Vector3f::Constant(0.05f)};
  model.rotations = {Eigen::Vector4f(1, 0, 0, 0), Eigen::Vector4f(2, 0.1f, 0, 0)};
  model.rotations[1].normalize();
  model.opacities = {0.6f, 0.8f};
  model.sh = {1, 1, 1, 0, 0, 0};
  camera::Camera camera{camera::CameraModel::kPinhole, 33, 33, {40, 40, 16.5, 16.5}};
  const camera::Pose pose;
  const GaussianRendering rendering = RenderGaussians(model, camera, pose);
  // The centre pixel (16, 16) has its centre on the first (front) Gaussian's mean: its alpha
  // there is its opacity, and the one behind adds to it.
  EXPECT_GE(rendering.color.at(16, 16, 3), 0.6f);

  Image ones(33, 33, 1, 1.0f);
  GaussianErrorAccumulator accumulator;
  AccumulateGaussianErrors(model, camera, pose, {}, ones, &accumulator);
  ASSERT_EQ(accumulator.weight.size(), 2u);
  double alpha_sum = 0;
  for (size_t i = 0; i < rendering.color.pixel_count(); ++i) {
    alpha_sum += rendering.color.data()[i * 4 + 3];
  }
  EXPECT_NEAR(accumulator.weight[0] + accumulator.weight[1], alpha_sum, 1e-3 * alpha_sum);
  EXPECT_GT(accumulator.weight[0], 0.6);  // at least its centre pixel
  for (int g = 0; g < 2; ++g) {
    EXPECT_NEAR(accumulator.weighted_error[g], accumulator.weight[g], 1e-9);
  }

  // Error 2 on the left half, NaN (invalid) on the right: only left pixels count.
  Image half(33, 33, 1, std::numeric_limits<float>::quiet_NaN());
  double left_alpha = 0;
  for (int y = 0; y < 33; ++y) {
    for (int x = 0; x < 16; ++x) {
      half.at(x, y) = 2.0f;
      left_alpha += rendering.color.at(x, y, 3);
    }
  }
  GaussianErrorAccumulator left;
  AccumulateGaussianErrors(model, camera, pose, {}, half, &left);
  EXPECT_NEAR(left.weight[0] + left.weight[1], left_alpha, 1e-3 * left_alpha);
  for (int g = 0; g < 2; ++g) EXPECT_NEAR(left.weighted_error[g], 2 * left.weight[g], 1e-6);

  // Accumulating a second view adds; a wrong size is an Error.
  const GaussianErrorAccumulator once = accumulator;
  AccumulateGaussianErrors(model, camera, pose, {}, ones, &accumulator);
  for (int g = 0; g < 2; ++g) EXPECT_NEAR(accumulator.weight[g], 2 * once.weight[g], 1e-9);
  EXPECT_THROW(AccumulateGaussianErrors(model, camera, pose, {}, Image(10, 10, 1), &accumulator),
               Error);
}

TEST(RenderGaussians, EmptyWhereNothingIsSeenAndBackgroundApplies) {
  GaussianModel model;
  model.positions = {Eigen::Vector3f(0, 0, -2)};  // behind the camera
  model.scales = {Eigen::Vector3f::Constant(0.1f)};
  model.rotations = {Eigen::Vector4f(1, 0, 0, 0)};
  model.opacities = {0.9f};
  model.sh = {1, 1, 1};
  camera::Camera camera{camera::CameraModel::kPinhole, 20, 10, {20, 20, 10, 5}};
  GaussianRenderOptions options;
  options.background = Eigen::Vector3f(0.25f, 0.5f, 1.0f);
  const GaussianRendering r = RenderGaussians(model, camera, camera::Pose(), options);
  for (int y = 0; y < 10; ++y) {
    for (int x = 0; x < 20; ++x) {
      EXPECT_EQ(r.color.at(x, y, 0), 0.25f);
      EXPECT_EQ(r.color.at(x, y, 2), 1.0f);
      EXPECT_EQ(r.color.at(x, y, 3), 0.0f);
      EXPECT_TRUE(std::isnan(r.depth.at(x, y)));
    }
  }
}

}  // namespace
}  // namespace rephoto::splat
