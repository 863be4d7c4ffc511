#include "rephoto/live/demo_capture.h"

#include <Eigen/Geometry>

#include "rephoto/core/file.h"
#include "rephoto/io/image_io.h"
#include "rephoto/live/sidecar.h"
#include "rephoto/render/render.h"
#include "rephoto/render/render_model.h"
#include "rephoto/suggest/next_views.h"
#include "rephoto/synth/demo_scene.h"

namespace rephoto::live {
namespace fs = std::filesystem;

DemoCapture::DemoCapture(int width, int height) {
  camera_.model = camera::CameraModel::kPinhole;
  camera_.width = width;
  camera_.height = height;
  camera_.params = {double(width), double(width), width / 2.0, height / 2.0};
  synth::DemoSceneOptions o;
  o.ground_cells = 200;
  o.object_bands = 150;
  truth_ = synth::MakeDemoMesh(o);
  model_ = std::make_unique<render::RenderModel>(truth_);
}

DemoCapture::~DemoCapture() = default;

Image DemoCapture::Photograph(const camera::Pose& pose, uint64_t seed) const {
  render::RenderOptions o;
  o.samples_per_pixel = 4;
  const render::Rephoto r = render::RenderRephoto(*model_, camera_, pose, o);
  return synth::SimulatePhoto(r.color, 1.0, 0.01, seed);
}

fs::path DemoCapture::Drop(const fs::path& folder, const std::string& stem,
                           const camera::Pose& pose, uint64_t seed) const {
  WriteTextFileAtomically(folder / (stem + ".json"), SidecarJson(camera_, pose).dump(2) + "\n");
  const Image photo = Photograph(pose, seed);
  const fs::path png = folder / (stem + ".png");
  WriteFileAtomically(png, [&](const fs::path& tmp) { io::WritePng(tmp, photo); });
  return png;
}

double UnseenObjectFraction(const DemoCapture& capture, const std::vector<camera::Pose>& poses) {
  const mesh::Mesh& m = capture.truth();
  std::vector<float> area(m.positions.size(), 0.f);
  for (const auto& t : m.faces) {
    const float a =
        0.5f * (m.positions[t[1]] - m.positions[t[0]]).cross(m.positions[t[2]] - m.positions[t[0]]).norm() / 3;
    for (uint32_t v : t) area[v] += a;
  }
  std::vector<uint8_t> seen(m.positions.size(), 0);
  const camera::UsableField field(capture.camera());
  for (const camera::Pose& p : poses) {
    const std::vector<uint8_t> s =
        suggest::VisibleVertices(capture.model(), m.normals, capture.camera(), p, &field);
    for (size_t i = 0; i < s.size(); ++i) seen[i] |= s[i];
  }
  double all = 0, unseen = 0;
  for (size_t i = 0; i < m.positions.size(); ++i) {
    const Eigen::Vector3f& x = m.positions[i];
    if (x.z() <= 0.02f || (x - Eigen::Vector3f(0, 0, 0.5f)).norm() > 0.6f) continue;
    all += area[i];
    if (!seen[i]) unseen += area[i];
  }
  return all > 0 ? unseen / all : 0.0;
}

}  // namespace rephoto::live
