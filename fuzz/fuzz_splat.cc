// libFuzzer target for the Gaussian splatting readers (rephoto/splat/gaussians.h) and the 3DGS
// cameras.json reader (rephoto/scene/cameras_json.h). The first input byte selects the reader
// (% 3): 0 = PLY (Inria, colour-only or compressed layout), 1 = .splat records,
// 2 = cameras.json; the rest is the file. A model that reads is also rendered at a 24x16 pinhole
// camera (at most 4096 Gaussians), so extreme but finite parameters reach the rasterizer.
#include <sstream>

#include "fuzz_common.h"
#include "rephoto/scene/cameras_json.h"
#include "rephoto/splat/gaussians.h"
#include "rephoto/splat/rasterize.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rephoto;
  if (size == 0) return 0;
  const int selector = data[0] % 3;
  std::istringstream in{std::string(fuzz::AsText(data + 1, size - 1))};
  if (selector == 2) {
    fuzz::AcceptsInput([&] { scene::ReadCamerasJson(in, "cameras.json", "/images"); });
    return 0;
  }
  splat::GaussianModel model;
  if (!fuzz::AcceptsInput([&] { model = splat::ReadGaussians(in, "model", selector == 1); })) {
    return 0;
  }
  if (model.size() <= 4096) {
    camera::Camera camera{camera::CameraModel::kPinhole, 24, 16, {20, 20, 12, 8}};
    const splat::GaussianRendering rendering =
        splat::RenderGaussians(model, camera, camera::Pose());
    (void)rendering;
  }
  return 0;
}
