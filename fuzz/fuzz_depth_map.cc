// libFuzzer target for the COLMAP depth-map reader (stereo/depth_maps/*.bin) through its
// istream entry point. Limits are lowered to 16 Mpx and 512 MiB (core/limits.h).
#include <sstream>

#include "fuzz_common.h"
#include "rephoto/core/limits.h"
#include "rephoto/ibr/depth_map_io.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rephoto::SetMaxPixels(uint64_t{16} << 20);
  rephoto::SetMaxMemoryBytes(uint64_t{512} << 20);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rephoto;
  std::istringstream in{std::string(fuzz::AsText(data, size))};
  fuzz::AcceptsInput([&] { ibr::ReadColmapDepthMap(in, "depth.bin"); });
  return 0;
}
