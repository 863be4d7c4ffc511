// Test fixtures of the report tests: small run directories written on the fly.
//
// Thread safety: test fixture; each call writes its own folder.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "rephoto/compare/compare.h"

namespace rephoto::report::testing {

// A hostile image name: HTML special characters must come out escaped.
inline const std::string kEvilName = "v<b>&'q\"";

// A `rephoto compare` run in `root`/run: photos of 40x32 random texture, renderings = photo +
// Gaussian noise of sigma noise * (1 + image index) with alpha 1 (image "v01": a transparent
// 10x8 block), `images` pairs named v00, v01, ... plus kEvilName (when with_evil_name), and
// one photo "zz_missing" without a rendering. Metrics 1-ncc, cb+cr and psnr.
compare::CompareResult MakeCompareRun(const std::filesystem::path& root, int images, double noise,
                                      uint64_t seed, bool with_evil_name = true);

// The evaluate-layout fixture written by hand in `dir` (no images): 4 ok folds and one failed
// fold (message with HTML in it); per_image.csv with fold column; per_fold.csv 1-ncc values
// 0.1, 0.4, 0.2, 0.3 (fold_00, 01, 02, 03), completeness 0.9, 0.8, 1.0, 0.7; summary.json
// (schema rephoto.evaluate/1) and run.json.
void WriteEvaluateRun(const std::filesystem::path& dir);

}  // namespace rephoto::report::testing
