// libFuzzer target for the Middlebury *_par.txt reader.
#include <sstream>

#include "fuzz_common.h"
#include "rephoto/scene/middlebury.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rephoto;
  std::istringstream in{std::string(fuzz::AsText(data, size))};
  fuzz::AcceptsInput(
      [&] { scene::ReadMiddlebury(in, "x_par.txt", scene::FixedImageSize(640, 480), "/images"); });
  return 0;
}
