// The resume keys of `rephoto evaluate` (cache_keys stage): each result in the run folder
// records the XXH3 key (eval/hash.h) of everything it depends on; a stage reuses a result whose
// recorded key equals the key computed now. All keys start with kKeyVersion (eval/state.h), so
// changing the meaning of a result recomputes every old one.
//
// What each key covers:
//   TrainKey          the training views (names, cameras, poses), the scene points and their
//                     tracks, and the training resolution
//   CommandKey        the command kind and template, the fold index, its train and test keys,
//                     --model (reconstruct) or the evaluation resolution (render)
//   ModelFileKey      the model file's content and each material's colour and texture content
//   DerivedModelKey   the fold's model key, plus the training key with --colorize, plus the
//                     defect settings: the coloured/degraded model.ply
//   GaussianModelKey  the Gaussian file's content and how it is rendered (mode, background,
//                     min_alpha: completeness depends on it)
//   RenderSettingsKey the built-in renderer's settings; CompareSettingsKey the comparison's
//   RenderKey         a view's rendering: the fold's render base key, the view and its camera
//   ViewKey           a view's record: base key, the external rendering's content, the view,
//                     its camera, photo and mask contents, the comparison settings
//
// Thread safety: pure functions of their arguments (ModelFileKey uses the FileHashCache, which
// is thread-safe).
#pragma once

#include <filesystem>
#include <string>

#include "rephoto/camera/camera.h"
#include "rephoto/eval/options.h"
#include "rephoto/eval/hash.h"
#include "rephoto/mesh/mesh.h"
#include "rephoto/scene/scene.h"

namespace rephoto::eval {

struct TestView;

void AddCamera(Hasher& h, const camera::Camera& camera);
void AddPose(Hasher& h, const camera::Pose& pose);

std::string TrainKey(const scene::Scene& train, int short_side);
std::string CompareSettingsKey(const EvaluateOptions& o);
std::string RenderSettingsKey(const EvaluateOptions& o);
std::string ModelFileKey(FileHashCache& hashes, const std::filesystem::path& path,
                         const mesh::Mesh& mesh);
std::string DerivedModelKey(const EvaluateOptions& o, const std::string& model_key,
                            const std::string& train_key);
std::string GaussianModelKey(const EvaluateOptions& o, const std::string& file_hash);
std::string RenderKey(const std::string& base_key, const TestView& test);
std::string ViewKey(const TestView& test, const std::string& base_key,
                    const std::string& render_hash, const std::string& compare_settings_key);

}  // namespace rephoto::eval
