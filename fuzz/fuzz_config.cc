// libFuzzer target for the experiment files: `rephoto evaluate --config` and `rephoto sweep`
// (TOML and JSON) through their text entry points. The first byte picks the format (bit 0:
// TOML or JSON) and the reader (bit 1: evaluate settings or sweep config); the rest is the file.
#include <string>

#include "fuzz_common.h"
#include "rephoto/eval/settings.h"
#include "rephoto/sweep/sweep.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rephoto;
  if (size == 0) return 0;
  const std::string_view text = fuzz::AsText(data + 1, size - 1);
  const std::string file = (data[0] & 1) != 0 ? "/experiments/exp.json" : "/experiments/exp.toml";
  fuzz::AcceptsInput([&] {
    if ((data[0] & 2) != 0) {
      sweep::LoadSweepConfigText(text, file);
    } else {
      eval::EvaluateOptions options;
      eval::LoadConfigText(text, file, &options);
      eval::SettingsJson(options).dump();
    }
  });
  return 0;
}
