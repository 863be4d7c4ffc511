// libFuzzer target for the Bundler reader. Input: the image list (list.txt), a NUL byte, then
// bundle.out. Without a NUL byte the whole input is bundle.out with an 11-image list.
#include <sstream>

#include "fuzz_common.h"
#include "rephoto/scene/bundler.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rephoto;
  const std::string_view input = fuzz::AsText(data, size);
  const size_t nul = input.find('\0');
  std::vector<std::string> names;
  std::string_view bundle = input;
  if (nul == std::string_view::npos) {
    for (int i = 0; i < 11; ++i) names.push_back("image" + std::to_string(i) + ".jpg");
  } else {
    std::istringstream list{std::string(input.substr(0, nul))};
    if (!fuzz::AcceptsInput([&] { names = scene::ReadBundlerImageList(list, "list.txt"); })) {
      return 0;
    }
    bundle = input.substr(nul + 1);
  }
  std::istringstream in{std::string(bundle)};
  fuzz::AcceptsInput([&] {
    scene::ReadBundler(in, "bundle.out", names, scene::FixedImageSize(640, 480), "/images");
  });
  return 0;
}
