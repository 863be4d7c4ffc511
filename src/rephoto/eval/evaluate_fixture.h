// Test fixture shared by the evaluate tests (compiled into them only): the small demo scene on
// disk and the evaluate options they start from.
//
// Thread safety: EvaluateTestScene writes the scene once (a function-local static); call it from
// the test thread.
#pragma once

#include <filesystem>

#include "rephoto/eval/evaluate.h"
#include "rephoto/synth/demo_files.h"

namespace rephoto::eval {

// 6 cameras of 160x120 around the demo object, photos with exposure differences (gain 1, 1.02,
// 1.04) and noise 0.01, in a folder whose name holds a space.
inline constexpr int kTestViews = 6;
const synth::DemoSceneFiles& EvaluateTestScene();

// That scene, writing to `out`: 1-NCC and Cb+Cr, no report, no projection.
EvaluateOptions EvaluateTestOptions(const std::filesystem::path& out);

}  // namespace rephoto::eval
