// libFuzzer target for the Strecha .camera reader.
#include <sstream>

#include "fuzz_common.h"
#include "rephoto/scene/strecha.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rephoto;
  std::istringstream in{std::string(fuzz::AsText(data, size))};
  fuzz::AcceptsInput([&] {
    const scene::CameraAndPose result = scene::ReadStrechaCamera(in, "0000.jpg.camera");
    // A camera that was accepted must be usable.
    result.camera.ImgFromCam(result.cam_from_world.CamFromWorld(Eigen::Vector3d(0, 0, 0)));
  });
  return 0;
}
