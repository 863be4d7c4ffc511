// libFuzzer target for the PLY reader (meshes and point clouds; ascii and both binary byte
// orders) through its istream entry point. The input is the whole file. The model memory
// limit is lowered to 256 MiB (core/limits.h) so that the reader's own check, not the
// fuzzer's -rss_limit_mb, stops headers that claim huge counts.
#include <sstream>

#include "fuzz_common.h"
#include "rephoto/core/limits.h"
#include "rephoto/mesh/ply.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rephoto::SetMaxMemoryBytes(uint64_t{256} << 20);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rephoto;
  std::istringstream in{std::string(fuzz::AsText(data, size))};
  fuzz::AcceptsInput([&] {
    const mesh::Mesh mesh = mesh::ReadPly(in, "model.ply", "/models");
    // A mesh that passed Validate must be safe to index.
    for (const mesh::Triangle& face : mesh.faces) {
      for (uint32_t index : face) {
        if (index >= mesh.positions.size()) __builtin_trap();
      }
    }
  });
  return 0;
}
