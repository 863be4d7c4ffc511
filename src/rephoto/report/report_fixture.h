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

// An evaluate-layout run in `dir` made for the 3D view (no images): the model is a flat grid
// of 41 x 41 vertices over [-1, 1]^2 at z = 0 (1600 quads, 3200 triangles; vertex colours
// r = (x + 1) / 2, g = (y + 1) / 2, b = 0.25) written as RUN/model.ply and named by run.json
// inputs.model.path; projected/1-ncc.ply (project::WriteProjectedPly) with vertex error
// 2 + x, except the vertices with x > 0.72 and y > 0.72 (grid values 0.75 .. 1), which no view
// saw (NaN), colour range [1, 3]; two folds (split/fold_00, split/fold_01: COLMAP text) over
// four PINHOLE cameras "cam_a.png" .. "cam_d.png" (640 x 480, f = 1000: each sees only part of
// the plane) at height 3 above the points (+-1.5, +-1.5, 0) looking at the origin, a and b
// evaluated in fold_00 and trained in fold_01, c and d the other way round; per_image.csv
// 1-ncc values 0.1, 0.2, 0.3, 0.4 for a .. d. run.json holds the values a report written
// before the projection saw: counters.projections 0, outputs.projected [], and
// split.cross_validated true where summary.json says false (a given model).
void WriteView3dRun(const std::filesystem::path& dir);

// The error WriteView3dRun gives a vertex at x (NaN where unseen).
double View3dRunError(double x, double y);

}  // namespace rephoto::report::testing
