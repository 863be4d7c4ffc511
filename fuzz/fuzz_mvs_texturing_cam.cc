// libFuzzer target for the mvs-texturing .cam reader.
#include <sstream>

#include "fuzz_common.h"
#include "rephoto/scene/mvs_texturing_cam.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rephoto;
  std::istringstream in{std::string(fuzz::AsText(data, size))};
  fuzz::AcceptsInput([&] {
    const scene::MvsTexturingCam cam = scene::ReadMvsTexturingCam(in, "a.cam");
    const camera::Camera camera = scene::MveCamera(cam.intrinsics, 480, 640, true, "a.cam");
    camera.ImgFromCam(cam.cam_from_world.CamFromWorld(Eigen::Vector3d(0, 0, 0)));
  });
  return 0;
}
