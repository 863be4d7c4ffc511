// The same results on every instruction-set path (core/isa.h): the small demo (vertex-coloured,
// noisy, simplified and view-dependently textured meshes, a point cloud; all eight metrics) run
// once per path this CPU has. Renderings, depth maps, error images and models are the same bytes
// on every path; the metric tables are bit-identical between AVX-512 and AVX2 and within 1e-6
// relative (1e-7 absolute near 0) on the baseline path (no FMA in the SSIM filters). Gaussians:
// splat/rasterize_test.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "rephoto/core/isa.h"
#include "rephoto/demo/demo.h"
#include "rephoto/testing/testing.h"

namespace rephoto::demo {
namespace {

namespace fs = std::filesystem;

std::string ReadBytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// Files of a run, by path relative to `root`: timings (run.json, demo.json, summary.json's
// seconds) and pages are left out, the CSV tables are compared by value.
std::map<std::string, fs::path> Outputs(const fs::path& root) {
  std::map<std::string, fs::path> files;
  for (const auto& entry : fs::recursive_directory_iterator(root)) {
    if (!entry.is_regular_file()) continue;
    const std::string ext = entry.path().extension().string();
    if (ext == ".json" || ext == ".html" || ext == ".log" || ext == ".lock") continue;
    files[fs::relative(entry.path(), root).string()] = entry.path();
  }
  return files;
}

std::vector<std::string> SplitCsv(const std::string& line) {
  std::vector<std::string> cells;
  std::stringstream in(line);
  for (std::string cell; std::getline(in, cell, ',');) cells.push_back(cell);
  return cells;
}

// Every cell equal, numbers within `relative` (0: the same text).
void ExpectSameTable(const fs::path& a, const fs::path& b, double relative) {
  std::istringstream in_a(ReadBytes(a)), in_b(ReadBytes(b));
  std::string line_a, line_b;
  int row = 0;
  while (std::getline(in_a, line_a)) {
    ASSERT_TRUE(std::getline(in_b, line_b)) << b << " has fewer rows";
    ++row;
    if (relative == 0 || line_a == line_b) {
      EXPECT_EQ(line_a, line_b) << a << " row " << row;
      continue;
    }
    const auto cells_a = SplitCsv(line_a), cells_b = SplitCsv(line_b);
    ASSERT_EQ(cells_a.size(), cells_b.size()) << a << " row " << row;
    for (size_t c = 0; c < cells_a.size(); ++c) {
      if (cells_a[c] == cells_b[c]) continue;
      char* end_a = nullptr;
      char* end_b = nullptr;
      const double va = std::strtod(cells_a[c].c_str(), &end_a);
      const double vb = std::strtod(cells_b[c].c_str(), &end_b);
      ASSERT_TRUE(*end_a == '\0' && *end_b == '\0')
          << a << " row " << row << ": '" << cells_a[c] << "' vs '" << cells_b[c] << "'";
      // Relative, or absolute 1e-7 for values near 0 (a DSSIM of 0.005 inherits SSIM's
      // absolute error).
      EXPECT_LE(std::abs(va - vb), std::max(relative * std::abs(va), 1e-7))
          << a << " row " << row << " column " << c;
    }
  }
  EXPECT_FALSE(std::getline(in_b, line_b)) << b << " has more rows";
}

TEST(CrossIsa, SmallDemoGivesTheSameResultsOnEveryPath) {
  const std::vector<core::Isa> isas = core::SupportedIsas();
  const fs::path root = testing::MakeTempDir();
  for (core::Isa isa : isas) {
    core::ScopedIsa scoped(isa);
    DemoOptions options;
    options.out = root / std::string(core::IsaName(isa));
    options.scene.image_width = 200;
    options.scene.image_height = 150;
    options.scene.camera_count = 4;
    options.scene.ground_cells = 100;
    options.scene.object_bands = 50;
    options.photo_samples_per_pixel = 4;
    options.report = false;
    options.suggestions = 0;
    RunDemo(options);
  }
  const std::string reference_name(core::IsaName(isas.back()));  // the best path
  const auto reference = Outputs(root / reference_name);
  size_t images = 0;
  for (core::Isa isa : isas) {
    if (isa == isas.back()) continue;
    SCOPED_TRACE(::testing::Message() << core::IsaName(isa) << " vs " << reference_name);
    const auto files = Outputs(root / std::string(core::IsaName(isa)));
    ASSERT_EQ(files.size(), reference.size());
    for (const auto& [name, path] : reference) {
      ASSERT_TRUE(files.count(name)) << name;
      if (fs::path(name).extension() == ".csv") {
        ExpectSameTable(path, files.at(name), isa == core::Isa::kBaseline ? 1e-6 : 0.0);
        continue;
      }
      const std::string ext = fs::path(name).extension().string();
      images += ext == ".png" || ext == ".exr";
      EXPECT_TRUE(ReadBytes(path) == ReadBytes(files.at(name))) << name << " differs";
    }
  }
  // Every compared path wrote and compared its images (100 PNG/EXR per path at this size). The
  // number of paths depends on the CPU: 3 with AVX-512, 2 on an AVX2 machine, 1 without AVX2.
  if (isas.size() > 1) EXPECT_GE(images, 100u * (isas.size() - 1));
}

}  // namespace
}  // namespace rephoto::demo
