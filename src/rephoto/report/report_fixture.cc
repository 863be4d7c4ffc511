#include "rephoto/report/report_fixture.h"

#include <fmt/format.h>

#include <random>

#include "rephoto/core/file.h"
#include "rephoto/io/image_io.h"

namespace rephoto::report::testing {
namespace fs = std::filesystem;

compare::CompareResult MakeCompareRun(const fs::path& root, int images, double noise, uint64_t seed,
                                      bool with_evil_name) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> uniform(0.15f, 0.85f);
  std::normal_distribution<float> gauss(0.f, 1.f);
  const int w = 40, h = 32;
  fs::create_directories(root / "photos");
  fs::create_directories(root / "renders");
  std::vector<std::string> names;
  for (int i = 0; i < images; ++i) names.push_back(fmt::format("v{:02d}", i));
  if (with_evil_name) names.push_back(kEvilName);
  for (size_t i = 0; i < names.size(); ++i) {
    Image photo(w, h, 3);
    for (size_t k = 0; k < photo.size(); ++k) photo.data()[k] = uniform(rng);
    Image render(w, h, 4);
    const float sigma = static_cast<float>(noise * (1 + static_cast<double>(i)));
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        for (int c = 0; c < 3; ++c) render.at(x, y, c) = photo.at(x, y, c) + sigma * gauss(rng);
        const bool hole = names[i] == "v01" && x >= 5 && x < 15 && y >= 4 && y < 12;
        render.at(x, y, 3) = hole ? 0.f : 1.f;
      }
    }
    io::WritePng(root / "photos" / (names[i] + ".png"), photo);
    io::WritePng(root / "renders" / (names[i] + ".png"), render);
  }
  Image lonely(w, h, 3, 0.5f);
  io::WritePng(root / "photos" / "zz_missing.png", lonely);
  compare::CompareOptions options;
  options.photos = root / "photos";
  options.renders = root / "renders";
  options.out = root / "run";
  options.metrics = {metrics::Metric::kOneMinusNcc, metrics::Metric::kCbCr, metrics::Metric::kPsnr};
  options.metric_options.window = 5;
  options.exposure.dark_threshold = -1;
  options.exposure.saturated_threshold = 2;
  return compare::RunCompare(options);
}

void WriteEvaluateRun(const fs::path& dir) {
  const std::string header =
      "fold,name,status,photo,render,width,height,resized,completeness,valid_photo_windows,"
      "valid_both_windows,1-ncc,1-ncc_evaluated,psnr,psnr_evaluated\n";
  WriteTextFileAtomically(
      dir / "per_image.csv",
      header +
          "fold_00,a,ok,/nonexistent/a.png,folds/fold_00/renders/a.png,40,30,0,0.9,1,1,0.12,100,"
          "20,120\n"
          "fold_00,b,ok,/nonexistent/b.png,folds/fold_00/renders/b.png,40,30,0,0.9,1,1,0.08,100,"
          "22,120\n"
          "fold_01,c,ok,/nonexistent/c.png,folds/fold_01/renders/c.png,40,30,0,0.8,1,1,0.4,90,"
          "15,120\n"
          "fold_02,d,ok,/nonexistent/d.png,folds/fold_02/renders/d.png,40,30,0,1,1,1,0.2,100,"
          "inf,120\n"
          "fold_03,e,ok,/nonexistent/e.png,folds/fold_03/renders/e.png,40,30,0,0.7,1,1,0.3,80,"
          "17,120\n"
          "fold_04,f,failed,/nonexistent/f.png,,,,,,,,,,,\n");
  WriteTextFileAtomically(dir / "per_fold.csv",
                          "fold,status,test_images,evaluated_images,seconds,completeness,1-ncc,"
                          "psnr\n"
                          "fold_00,ok,2,2,1.5,0.9,0.1,21\n"
                          "fold_01,ok,1,1,1.25,0.8,0.4,15\n"
                          "fold_02,ok,1,1,1,1,0.2,inf\n"
                          "fold_03,ok,1,1,1,0.7,0.3,17\n"
                          "fold_04,failed,1,0,0.5,,,\n");
  WriteTextFileAtomically(dir / "summary.json", R"({
  "schema": "rephoto.evaluate/1",
  "tool_version": "0.1.0",
  "scene": "/data/scene<x>",
  "scheme": "kfold:5",
  "folds": 5,
  "failed_folds": [{"fold": "fold_04", "message": "reconstruct exited with 1: <script>alert(1)</script>"}],
  "missing": [],
  "completeness": {"across_folds": {"mean": 0.85}, "over_images": {"mean": 0.86}, "pooled": 0.86},
  "1-ncc": {"across_folds": {"mean": 0.25}, "over_images": {"mean": 0.22}, "pooled": 0.2}
}
)");
  WriteTextFileAtomically(dir / "run.json", R"({
  "schema": "rephoto.evaluate/1",
  "tool_version": "0.1.0",
  "command_line": "rephoto evaluate scene --reconstruct 'echo <b>hi</b>'",
  "settings": {"representation": "mesh", "window": 9, "metrics": ["1-ncc", "psnr"]},
  "timings": {"total": 12.5}
}
)");
}

}  // namespace rephoto::report::testing
