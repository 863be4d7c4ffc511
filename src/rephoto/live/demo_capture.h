// A simulated capture of the demo scene (synth/demo_scene.h) for `rephoto live`: the
// ground-truth scene photographed at any pose and dropped into a watched folder as a photo and
// its pose sidecar, as a tracked rig would. Used by the closed-loop experiment (closed_loop.h),
// the tests and the demo.
//
// Photos: the ground-truth mesh (vertex colours) rendered with 4 stratified samples per pixel,
// then synth::SimulatePhoto (gain 1, noise sigma 0.01, seed = the photo's index), 8-bit PNG.
// Camera: PINHOLE, focal length = width, principal point at the centre.
// Thread safety: one DemoCapture per thread (rendering is parallel inside).
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "rephoto/camera/camera.h"
#include "rephoto/core/image.h"
#include "rephoto/mesh/mesh.h"

namespace rephoto::render {
class RenderModel;
}

namespace rephoto::live {

// The pose of a camera at `center` looking at `target`, its x axis horizontal (z up):
// camera::LookAt.
using camera::LookAt;

class DemoCapture {
 public:
  // The demo scene at reduced tessellation (ground 200 cells, object 150 bands).
  DemoCapture(int width, int height);
  ~DemoCapture();
  const camera::Camera& camera() const { return camera_; }
  const mesh::Mesh& truth() const { return truth_; }
  const render::RenderModel& model() const { return *model_; }
  // The photo at `pose` (RGB).
  Image Photograph(const camera::Pose& pose, uint64_t seed) const;
  // Writes <folder>/<stem>.json (the sidecar) and then <folder>/<stem>.png, each atomically
  // (temporary name + rename, so a watcher sees IN_MOVED_TO). Returns the PNG's path.
  std::filesystem::path Drop(const std::filesystem::path& folder, const std::string& stem,
                             const camera::Pose& pose, uint64_t seed) const;

 private:
  camera::Camera camera_;
  mesh::Mesh truth_;
  std::unique_ptr<render::RenderModel> model_;
};

// Area-weighted fraction of the demo object's surface (vertices within 0.6 of (0, 0, 0.5) and
// above z = 0.02) that no pose sees by render/visibility.h's rule (suggest::VisibleVertices):
// the ground truth of "unseen surface".
double UnseenObjectFraction(const DemoCapture& capture, const std::vector<camera::Pose>& poses);

}  // namespace rephoto::live
