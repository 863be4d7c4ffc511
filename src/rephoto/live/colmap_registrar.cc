#include "rephoto/live/colmap_registrar.h"

#include "rephoto/core/error.h"

namespace rephoto::live {

std::unique_ptr<Registrar> MakeColmapRegistrar(const std::filesystem::path&, const std::string&,
                                               int) {
  throw UsageError("--colmap: COLMAP registration is not built yet");
}

}  // namespace rephoto::live
