// libFuzzer target for the transforms.json reader: any input must end in a Scene or a
// rephoto::Error, never a crash or a sanitizer report. A Scene that was read is written back.
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "fuzz_common.h"
#include "rephoto/scene/transforms_json.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rephoto::scene;
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  rephoto::fuzz::AcceptsInput([&] {
    const Scene scene = ReadTransformsJson(in, "transforms.json", "/nonexistent-fuzz-root",
                                           FixedImageSize(640, 480));
    TransformsJsonFromScene(scene, "/nonexistent-fuzz-root");
  });
  return 0;
}
