// libFuzzer target for the MVE meta.ini reader and MVE's intrinsics conversion.
#include <sstream>

#include "fuzz_common.h"
#include "rephoto/scene/mve.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rephoto;
  std::istringstream in{std::string(fuzz::AsText(data, size))};
  fuzz::AcceptsInput([&] {
    const scene::MveViewMeta meta = scene::ReadMveMetaIni(in, "meta.ini");
    if (meta.intrinsics) {
      for (bool distortion : {false, true}) {
        const camera::Camera camera =
            scene::MveCamera(*meta.intrinsics, 640, 480, distortion, "meta.ini");
        camera.ImgFromCam(meta.cam_from_world.CamFromWorld(Eigen::Vector3d(0, 0, 0)));
      }
    }
  });
  return 0;
}
