// libFuzzer target for the COLMAP readers: the first byte picks the reader, the rest is the
// file. Any input must end in a result or a rephoto::Error, never a crash or a sanitizer report.
// When all three text readers succeed on thirds of the input, the records are also linked.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "fuzz_common.h"
#include "rephoto/scene/colmap.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rephoto::scene;
  using rephoto::fuzz::AcceptsInput;
  if (size == 0) return 0;
  const std::string input(reinterpret_cast<const char*>(data) + 1, size - 1);
  std::istringstream in(input);
  switch (data[0] % 7) {
    case 0:
      AcceptsInput([&] { ReadColmapCamerasText(in, "cameras.txt"); });
      break;
    case 1:
      AcceptsInput([&] { ReadColmapImagesText(in, "images.txt"); });
      break;
    case 2:
      AcceptsInput([&] { ReadColmapPoints3DText(in, "points3D.txt"); });
      break;
    case 3:
      AcceptsInput([&] { ReadColmapCamerasBinary(in, "cameras.bin"); });
      break;
    case 4:
      AcceptsInput([&] { ReadColmapImagesBinary(in, "images.bin"); });
      break;
    case 5:
      AcceptsInput([&] { ReadColmapPoints3DBinary(in, "points3D.bin"); });
      break;
    case 6: {
      // Three files separated by NUL bytes, read and linked into a Scene.
      const size_t a = input.find('\0');
      const size_t b = a == std::string::npos ? a : input.find('\0', a + 1);
      if (b == std::string::npos) break;
      std::istringstream cameras(input.substr(0, a)), images(input.substr(a + 1, b - a - 1)),
          points(input.substr(b + 1));
      ColmapModel model;
      if (AcceptsInput([&] { model.cameras = ReadColmapCamerasText(cameras, "cameras.txt"); }) &&
          AcceptsInput([&] { model.images = ReadColmapImagesText(images, "images.txt"); }) &&
          AcceptsInput([&] { model.points = ReadColmapPoints3DText(points, "points3D.txt"); })) {
        AcceptsInput([&] { SceneFromColmap(model, "images"); });
      }
      break;
    }
  }
  return 0;
}
