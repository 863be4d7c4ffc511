// The `--compat` stage of `rephoto evaluate`: the numbers novel-view-synthesis papers publish,
// computed on the same renderings as rephoto's own metrics and written in the reference tools'
// own formats, so that one command gives both.
//
// Per view (CompareViewCompat, in the view stage after rephoto's own comparison): the rendering
// as written (renders/<stem>.png, or the external renderer's file) and the photo as compared
// (the original file, or the eval_short_side copy) go through compare::CompareOptions::compat
// (compare/compat_compare.h: every pixel, no masks, photo alpha composited over
// EvaluateOptions::background, the rendering's alpha dropped): the preset's metrics
// (CompatMetrics), stored in the view record with rephoto's own.
//
// Per run (WriteCompatNumbers, in the aggregate stage), over the evaluated views of all folds
// in name order (a --compat run normally has one fold, every:8):
//   per_image.csv    columns <preset>_<metric> ("3dgs_psnr", "3dgs_ssim") after rephoto's own
//   summary.json     "compat": {preset, background, method, images, metrics: {<metric>:
//                    {mean, std, over_images}}, files}
//   3dgs:            RUN/results.json   {METHOD: {"SSIM": mean, "PSNR": mean[, "LPIPS": mean]}}
//                    RUN/per_view.json  {METHOD: {"SSIM": {<render file>: value, ...}, ...}}
//                    (json.dump(indent=True): one space per level, as metrics.py writes them)
//                    RUN/metrics.txt    what metrics.py prints: "Scene: RUN", "Method: METHOD",
//                    "  SSIM : {:>12.7f}" (SSIM, PSNR, LPIPS in that order), a blank line.
//                    METHOD: "ours_<N>" when the model is .../iteration_<N>/<file> (the folder
//                    render.py names after the iteration), else "rephoto". <render file>: the
//                    rendering's file name in the fold's renders (render.py names them 00000.png
//                    ... in the same sorted-name order).
//   nerfstudio:      RUN/output.json    what ns-eval writes (json.dumps(indent=2)):
//                    {"experiment_name": the scene folder's name, "method_name": "rephoto",
//                    "checkpoint": the model file or the --render command, "results": {"psnr":
//                    mean, "psnr_std": std, "ssim": ..., "ssim_std": ...[, "lpips", "lpips_std"]}}
//                    (std: torch.std_mean, n - 1); ns-eval's timing entries (num_rays_per_sec,
//                    fps) are not written: they time nerfstudio's renderer.
// Means are of the per-image values (PSNR: the mean of the images' PSNRs), as both references
// compute them. Values are doubles (the references compute in float32 on the GPU: they differ
// in about the 6th decimal); an infinite value (the PSNR of an identical image) is "inf", a
// missing one (the std of one image) null, where Python writes Infinity and NaN.
// Without --compat these files are removed from the run folder (they would describe an earlier
// run).
//
// Thread safety: CompareViewCompat uses the caller's workspace; WriteCompatNumbers runs on one
// thread.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "rephoto/eval/state.h"

namespace rephoto::eval {

// The compare settings of the preset: compat, compat_background = options.background,
// metrics = CompatMetrics(options), no error images. Only meaningful with options.compat.
compare::CompareOptions CompatCompareSettings(const EvaluateOptions& options);

// The preset's values of one view, in CompatMetrics order (see above). Throws Error naming
// the rendering when its size is not the photo's.
std::vector<compare::MetricValue> CompareViewCompat(const EvaluateOptions& options,
                                                    const std::string& stem,
                                                    const std::filesystem::path& photo_path,
                                                    const std::filesystem::path& render_path,
                                                    const Image& photo, const Image& render,
                                                    compare::CompareWorkspace* workspace);

// per_image.csv's compat columns: "<preset>_<metric>" in CompatMetrics order (none without
// a preset).
std::vector<std::string> CompatColumns(const EvaluateOptions& options);

// The method name of the reference files (see above).
std::string CompatMethodName(const EvaluateOptions& options);

// Aggregates the evaluated views' compat values (result->compat, result->compat_text), writes
// the preset's reference files (see above) and returns summary.json's "compat" block (null
// without a preset, when the files are removed instead).
nlohmann::ordered_json WriteCompatNumbers(const RunContext& s, const std::vector<FoldPlan>& plans,
                                          const std::vector<FoldOutcome>& folds,
                                          EvaluateResult* result);

}  // namespace rephoto::eval
