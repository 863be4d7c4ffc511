// libFuzzer target for the torch.save reader (src/rephoto/lpips/torch_file.h) through its
// in-memory entry point: zip and legacy containers, the pickle subset, tensor views. Seeds: the
// two tiny files of src/rephoto/lpips/testdata (scripts/fuzz.sh). The memory limit is lowered
// to 256 MiB so that the reader's own check, not the fuzzer's -rss_limit_mb, stops tensors
// that claim huge sizes.
#include "fuzz_common.h"
#include "rephoto/core/limits.h"
#include "rephoto/lpips/torch_file.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  rephoto::SetMaxMemoryBytes(uint64_t{256} << 20);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rephoto;
  fuzz::AcceptsInput([&] {
    const lpips::StateDict dict = lpips::ParseTorchFile(fuzz::AsText(data, size), "fuzz.pth");
    // Every float tensor holds exactly product(shape) values.
    for (const auto& [name, tensor] : dict) {
      size_t count = 1;
      for (int64_t s : tensor.shape) count *= static_cast<size_t>(s);
      if (!tensor.values.empty() && tensor.values.size() != count) __builtin_trap();
    }
  });
  return 0;
}
