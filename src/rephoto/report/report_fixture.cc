#include "rephoto/report/report_fixture.h"

#include <fmt/format.h>

#include <random>

#include "rephoto/core/file.h"
#include "rephoto/io/image_io.h"
#include "rephoto/mesh/ply.h"
#include "rephoto/project/project.h"
#include "rephoto/scene/colmap.h"

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

double View3dRunError(double x, double y) {
  return x > 0.72 && y > 0.72 ? std::nan("") : 2 + x;
}

void WriteView3dRun(const fs::path& dir) {
  fs::create_directories(dir);
  const int n = 41;
  mesh::Mesh model;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const float x = -1.f + 2.f * i / (n - 1), y = -1.f + 2.f * j / (n - 1);
      model.positions.push_back({x, y, 0.f});
      model.colors.push_back({(x + 1) / 2, (y + 1) / 2, 0.25f});
    }
  }
  for (int j = 0; j + 1 < n; ++j) {
    for (int i = 0; i + 1 < n; ++i) {
      const uint32_t a = j * n + i, b = a + 1, c = a + n, d = c + 1;
      model.faces.push_back({a, b, d});
      model.faces.push_back({a, d, c});
    }
  }
  mesh::WritePly(dir / "model.ply", model);
  project::ProjectResult projected;
  for (const Eigen::Vector3f& p : model.positions) {
    const double e = View3dRunError(p.x(), p.y());
    projected.vertex_error.push_back(static_cast<float>(e));
    projected.view_count.push_back(std::isnan(e) ? 0 : 2);
    projected.seen_vertices += std::isnan(e) ? 0 : 1;
  }
  projected.low = 1;
  projected.high = 3;
  project::WriteProjectedPly(model, projected, dir / "projected" / "1-ncc.ply");

  // Cameras at height 3 above (+-1.5, +-1.5, 0), looking at the origin, x axis horizontal.
  camera::Camera camera;
  camera.model = camera::CameraModel::kPinhole;
  camera.width = 640;
  camera.height = 480;
  camera.params = {1000, 1000, 320, 240};  // narrow: not every camera sees the whole plane
  const std::vector<std::pair<std::string, Eigen::Vector3d>> centres = {
      {"cam_a.png", {1.5, 1.5, 3}}, {"cam_b.png", {-1.5, 1.5, 3}},
      {"cam_c.png", {-1.5, -1.5, 3}}, {"cam_d.png", {1.5, -1.5, 3}}};
  std::vector<scene::View> views;
  for (const auto& [name, centre] : centres) {
    const Eigen::Vector3d z = (-centre).normalized();  // viewing direction
    const Eigen::Vector3d x = z.cross(Eigen::Vector3d::UnitZ()).normalized();
    const Eigen::Vector3d y = z.cross(x);
    scene::View view;
    view.name = name;
    view.camera_id = 1;
    view.cam_from_world.rotation.row(0) = x.transpose();
    view.cam_from_world.rotation.row(1) = y.transpose();
    view.cam_from_world.rotation.row(2) = z.transpose();
    view.cam_from_world.translation = -view.cam_from_world.rotation * centre;
    views.push_back(view);
  }
  auto write = [&](const fs::path& folder, std::vector<int> which) {
    scene::Scene part;
    part.cameras[1] = camera;
    for (int k : which) part.views.push_back(views[k]);
    scene::WriteColmap(part, folder, scene::ColmapFormat::kText);
  };
  write(dir / "split" / "fold_00" / "test" / "sparse", {0, 1});
  write(dir / "split" / "fold_00" / "train" / "sparse", {2, 3});
  write(dir / "split" / "fold_01" / "test" / "sparse", {2, 3});
  write(dir / "split" / "fold_01" / "train" / "sparse", {0, 1});

  WriteTextFileAtomically(dir / "per_image.csv",
                          "fold,name,status,photo,render,width,height,resized,completeness,"
                          "valid_photo_windows,valid_both_windows,1-ncc,1-ncc_evaluated\n"
                          "fold_00,cam_a,ok,,,640,480,0,1,1,1,0.1,100\n"
                          "fold_00,cam_b,ok,,,640,480,0,1,1,1,0.2,100\n"
                          "fold_01,cam_c,ok,,,640,480,0,1,1,1,0.3,100\n"
                          "fold_01,cam_d,ok,,,640,480,0,1,1,1,0.4,100\n");
  WriteTextFileAtomically(dir / "per_fold.csv",
                          "fold,status,test_images,evaluated_images,seconds,completeness,1-ncc\n"
                          "fold_00,ok,2,2,1,1,0.15\n"
                          "fold_01,ok,2,2,1,1,0.35\n");
  WriteTextFileAtomically(dir / "summary.json", R"({
  "schema": "rephoto.evaluate/1",
  "scheme": "kfold:2",
  "folds": 2,
  "cross_validated": false,
  "failed_folds": [],
  "missing": []
}
)");
  WriteTextFileAtomically(dir / "run.json", fmt::format(R"({{
  "schema": "rephoto.evaluate/1",
  "status": "ok",
  "settings": {{"representation": "mesh"}},
  "inputs": {{"model": {{"path": "{}"}}}},
  "split": {{"scheme": "kfold:2", "cross_validated": true, "folder": "split"}},
  "counters": {{"projections": 0}},
  "outputs": {{"projected": [], "report": null}}
}}
)",
                                                        (dir / "model.ply").generic_string()));
}

}  // namespace rephoto::report::testing
