// The 3D view (view3d.h) in headless Chromium with software WebGL: a run report and a
// comparison report built from the fixture of report_fixture.h by the same code as every
// report, checked by tests/browser/view3d_check.py (vertex colours against the jet map of
// their errors at their projected screen positions, a click on a camera frustum naming its
// photo, a click on the surface listing the views that see the point, no console errors; for the comparison report also the ranking notes within a 1280 px
// window and the boxplot labels inside their plots). The demo's report is checked the same way
// by hand (docs/view3d.md). Needs chromium and python3-websocket (scripts/install-deps.sh).
#include <gtest/gtest.h>

#include "rephoto/core/file.h"
#include "rephoto/report/report.h"
#include "rephoto/report/report_fixture.h"
#include "rephoto/scene/colmap.h"
#include "rephoto/testing/testing.h"

namespace rephoto::report {
namespace {
namespace fs = std::filesystem;

int RunCheck(const fs::path& report, const std::string& flags, const fs::path& log) {
  const fs::path script = rephoto::testing::SourceDir() / "tests" / "browser" / "view3d_check.py";
  const std::string command = "timeout 300 /usr/bin/python3 '" + script.string() + "' '" +
                              report.string() + "' " + flags + " > '" + log.string() + "' 2>&1";
  return std::system(command.c_str());
}

TEST(View3dBrowser, ColoursAndCameraPickingInHeadlessChromium) {
  ASSERT_EQ(std::system("command -v chromium >/dev/null && /usr/bin/python3 -c 'import "
                        "websocket' 2>/dev/null"),
            0)
      << "install chromium and python3-websocket (scripts/install-deps.sh)";
  const fs::path root = rephoto::testing::MakeTempDir();
  testing::WriteView3dRun(root / "plane");
  // A second run of the same model with half the completeness (a note in the ranking) and
  // other image errors.
  testing::WriteView3dRun(root / "Simplified (3 of 4 folds, coarse)");
  WriteTextFileAtomically(root / "Simplified (3 of 4 folds, coarse)" / "per_image.csv",
                          "fold,name,status,photo,render,width,height,resized,completeness,"
                          "valid_photo_windows,valid_both_windows,1-ncc,1-ncc_evaluated\n"
                          "fold_00,cam_a,ok,,,640,480,0,0.5,1,1,0.1,100\n"
                          "fold_00,cam_b,ok,,,640,480,0,0.5,1,1,0.5,100\n"
                          "fold_01,cam_c,ok,,,640,480,0,0.5,1,1,0.3,100\n"
                          "fold_01,cam_d,ok,,,640,480,0,0.5,1,1,0.9,100\n");
  WriteTextFileAtomically(root / "Simplified (3 of 4 folds, coarse)" / "per_fold.csv",
                          "fold,status,test_images,evaluated_images,seconds,completeness,1-ncc\n"
                          "fold_00,ok,2,2,1,0.5,0.3\n"
                          "fold_01,ok,2,2,1,0.5,0.6\n");
  // A suggested view (rephoto suggest's files) above the plane.
  const fs::path next = root / "next";
  {
    scene::Scene s;
    camera::Camera camera;
    camera.model = camera::CameraModel::kPinhole;
    camera.width = 640;
    camera.height = 480;
    camera.params = {500, 500, 320, 240};
    s.cameras[1] = camera;
    scene::View view;
    view.name = "suggest_00.png";
    view.camera_id = 1;
    view.cam_from_world.rotation = Eigen::Vector3d(1, -1, -1).asDiagonal();  // looks down
    view.cam_from_world.translation = {0, 0, 2.5};                            // centre (0, 0, 2.5)
    s.views.push_back(view);
    scene::WriteColmap(s, next / "sparse", scene::ColmapFormat::kText);
    WriteTextFileAtomically(next / "suggestions.json",
                            R"({"schema": "rephoto.suggest/1", "unobserved_area": 0.1,
      "suggestions": [{"name": "suggest_00.png", "unobserved_area": 0.05, "mean_error": null}]})");
  }
  WriteRunReport(root / "plane", root / "run.html");
  WriteCollectionReport({{.label = "plane", .run_dir = root / "plane"},
                         {.label = "Simplified (3 of 4 folds, coarse)",
                          .run_dir = root / "Simplified (3 of 4 folds, coarse)"}},
                        root / "collection.html", {.suggestions = next});
  const fs::path run_log = root / "run.log", collection_log = root / "collection.log";
  EXPECT_EQ(RunCheck(root / "run.html",
                     "--surface-click --screenshot '" + (root / "run.png").string() + "'",
                     run_log),
            0)
      << ReadFileToString(run_log);
  std::printf("%s", ReadFileToString(run_log).c_str());
  EXPECT_NE(ReadFileToString(run_log).find("all checks passed"), std::string::npos);
  EXPECT_EQ(RunCheck(root / "collection.html", "--note-visible --boxplot-labels --width 1280",
                     collection_log),
            0)
      << ReadFileToString(collection_log);
  std::printf("%s", ReadFileToString(collection_log).c_str());
  EXPECT_NE(ReadFileToString(collection_log).find("all checks passed"), std::string::npos);
}

}  // namespace
}  // namespace rephoto::report
