// Registering photos without a pose sidecar with COLMAP 3.8 (see colmap_registrar.cc).
#pragma once

#include <filesystem>
#include <memory>
#include <string>

#include "rephoto/live/live_session.h"

namespace rephoto::live {

// A Registrar driving `colmap` subprocesses in `workspace` (created). `bootstrap` = photos to
// wait for before the first reconstruction (0 = 5).
std::unique_ptr<Registrar> MakeColmapRegistrar(const std::filesystem::path& workspace,
                                               const std::string& colmap_binary, int bootstrap);

}  // namespace rephoto::live
