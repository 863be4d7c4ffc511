// libFuzzer target for the OBJ + MTL reader through its istream entry point. Input: the OBJ
// file, optionally a NUL byte and the MTL file that every mtllib statement reads (no file is
// ever opened). tinyobjloader itself is compiled into the target (tinyobj_implementation.cc)
// so that libFuzzer sees its coverage and the sanitizers check it.
#include <sstream>

#include "fuzz_common.h"
#include "rephoto/core/limits.h"
#include "rephoto/mesh/obj.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rephoto::SetMaxMemoryBytes(uint64_t{256} << 20);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rephoto;
  const std::string_view input = fuzz::AsText(data, size);
  const size_t nul = input.find('\0');
  std::istringstream obj{std::string(input.substr(0, nul))};
  std::istringstream mtl{nul == std::string_view::npos ? std::string()
                                                       : std::string(input.substr(nul + 1))};
  fuzz::AcceptsInput([&] {
    const mesh::Mesh mesh = mesh::ReadObj(obj, "model.obj", "/models", &mtl);
    for (const mesh::Triangle& face : mesh.faces) {
      for (uint32_t index : face) {
        if (index >= mesh.positions.size()) __builtin_trap();
      }
    }
  });
  return 0;
}
