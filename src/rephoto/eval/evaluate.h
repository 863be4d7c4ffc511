// `rephoto evaluate`: virtual rephotography end to end (paper Section 3.1): split the photos,
// obtain each fold's reconstruction from its training photos, rephotograph it at the fold's
// held-out cameras, compare with the photos, aggregate per image / fold / dataset, project the
// error onto the model and write a report. The run directory layout is the contract in
// docs/run-folder.md (mirrored in the comments below).
//
// Model sources (exactly one):
//   kModel        EvaluateOptions::model alone: one model file for every fold (a global method,
//                 no cross-validation needed, paper Section 4.4), rendered by the built-in
//                 renderer. With `colorize`, each fold's copy is coloured from that fold's
//                 TRAINING photos only (render::ColorizeMesh), which makes it a proper
//                 cross-validated reconstruction of the colours.
//   kReconstruct  `reconstruct` = a command template run once per fold through /bin/sh -c, then
//                 `model` (a path relative to {out}) is read as the fold's model (mesh or point
//                 cloud; PLY or OBJ) and rendered by the built-in renderer.
//   kRender       `render` = a command template of an external renderer (NeRF, 3DGS, IBR) that
//                 writes one RGBA image per test view, named <test stem>.<png|jpg|jpeg|exr|pfm>,
//                 into {out}; compared as they are (alpha = coverage; without alpha pure black =
//                 not covered).
// Placeholders of both templates (each value shell-quoted; syntax in eval/command_template.h):
//   {train}            the fold's training scene folder: {train}/sparse (COLMAP text model of
//                      the training views with their sparse points), {train}/transforms.json
//   {sparse} {transforms} those two paths
//   {images}           the folder the training image names are relative to; it holds only the
//                      fold's training photos (RUN/folds/fold_XX/train/images: hard links, or
//                      symbolic links across file systems, to the photos; the downscaled PNGs
//                      with train_short_side), so a pipeline that takes every image in it cannot
//                      see a test photo
//   {train_list}       train.txt: the training image names, one per line
//   {test} {test_sparse} {test_transforms} {test_list}   the same for the held-out cameras (no
//                      points); at the evaluation resolution when eval_short_side is set
//   {out}              the fold's empty output folder RUN/folds/fold_XX/reconstruction
//   {fold}             the fold index (0-based)
//   {threads}          threads the command should use: all threads / jobs (at least 1)
// A command fails its fold (other folds go on) when it cannot be started, exits non-zero, is
// killed by a signal, writes nothing into {out}, writes no model at {out}/model or a model that
// cannot be read, or (render) misses a test image or writes one of the wrong size. The message
// names the fold, the command and its log file RUN/logs/fold_XX.<reconstruct|render>.log
// (stdout and stderr of the command). The run then returns ExitCode::kIncomplete and lists
// the failed folds in summary.json and per_fold.csv.
//
// Split scheme: split/split.h syntax. Default: "every:8" with a --compat preset (the test views
// of published tables), else "none" for a model alone without colorize (all photos are test
// photos of the one model: a fit error, paper 4.4), otherwise "kfold:5" (or "loo" when there
// are fewer than 5 photos).
//
// Photos missing on disk (a view whose image file does not exist) are left out of the split:
// they can neither train nor be compared. They are listed as warnings, in run.json and in
// summary.json "missing", and the run returns ExitCode::kIncomplete; the rest is evaluated.
//
// Sweeps (paper Section 4.2):
//   train_count N > 0: each fold trains on a deterministic subset of N of its training views
//     (the sorted names shuffled by split::SeededShuffle with seed train_seed + fold index).
//   train_short_side PX > 0: the fold's training photos are downscaled (area filter, see
//     compare/resample.h) so that the shorter side is PX (never upscaled), written as 8-bit PNG
//     RUN/folds/fold_XX/train/images/<name without extension>.png, and the training scene's
//     cameras are scaled with Camera::Scaled (observations too); the training scene then names
//     the PNGs. A photo whose shorter side is already at most PX is linked as it is (no
//     re-encoding), under its own name. Either option writes the fold's own training scene
//     RUN/folds/fold_XX/train/ (sparse, transforms.json, train.txt, images/), which {train} etc.
//     then point to.
//   eval_short_side PX > 0: rephotos are rendered and photos compared at the size whose shorter
//     side is PX (never upscaled): the test cameras are scaled (Camera::Scaled) and the photos
//     (and photo masks, conservatively) downscaled once with the area filter into
//     RUN/cache/eval_photos/<stem>.png (16-bit PNG, reused while the photo is unchanged).
//
// Parallelism: the built-in renderer and the metrics are multi-threaded (TBB). External
// commands run `jobs` folds at a time in background threads ({threads} = all threads / jobs);
// rephoto's own work (colouring, rendering, comparing) runs on the calling thread fold after
// fold, overlapping with the commands of the next folds. The results do not depend on `jobs`.
//
// Resume: every result carries a key, the XXH3 hash (eval/hash.h) of everything it depends on
// (scene cameras and poses, photo and mask contents, model file content incl. textures, the
// command template, and the settings that change it). A rerun with the same --out skips
// folds whose reconstruction key matches (fold.json) and views whose record
// (folds/fold_XX/views/<stem>.json, written last) holds the matching key; changed inputs or
// settings recompute exactly what they affect. An interrupted run (SIGINT/SIGTERM with
// handle_interrupts, or InterruptRequested()) stops the running commands, finishes the view
// in flight and throws Error "interrupted ... rerun the same command to resume". A run
// directory that holds a run of another scene (different set of image names) is an Error.
//
// Outputs in `out` (every file written atomically; the full contract with all fields is
// docs/run-folder.md):
//   run.json       schema "rephoto.evaluate/1": tool version, command line, resolved settings
//                  (eval/settings.h names), scene identity, inputs with XXH3 content hashes
//                  (scene, model, photos, missing photos), the split, timings in seconds
//                  {total, external, rephoto: {total, split, prepare, colorize, render, compare,
//                  aggregate, project, report}}, counters, per-fold status, outputs (projected
//                  PLYs, report, or why they are missing). status: running | interrupted | ok |
//                  incomplete.
//   manifest.json  the independent tasks: one "<fold>/reconstruct" or "<fold>/render" task per
//                  fold when a command is used, one "<fold>/<stem>" task per test view, each with
//                  its key, inputs, outputs and dependencies, so a scheduler could run them
//                  elsewhere and this command would then reuse their records.
//   split/         exactly what split::WriteSplit writes (photos that exist only).
//   folds/fold_XX/ reconstruction/ (the command's {out}), model.ply + model.key (the coloured
//                  model, --colorize), train/ and test/ (only when they differ from split/, see
//                  Sweeps), renders/<stem>.png (RGBA 8-bit, alpha = coverage) and
//                  <stem>.depth.exr (built-in renderer, WritesDepthImages), errors/
//                  <stem>.<metric>.exr|png (ErrorImageMetrics: by default 1-NCC's only),
//                  views/<stem>.json (the view's result and key, written last), fold.json.
//                  <stem>: the view name's file name without extension, or its relative path
//                  without extension when two views share a file name.
//   logs/fold_XX.reconstruct.log, logs/fold_XX.render.log
//   per_image.csv  fold, then compare's per_image.csv columns, sorted by fold then name; status
//                  ok | failed (the fold or the view failed; measurements empty); photo = the
//                  absolute path of the photo compared (the cached downscaled copy with
//                  eval_short_side), render relative to RUN.
//   per_fold.csv   fold, status, test_images, evaluated_images, seconds (recorded compute time),
//                  completeness, <metric>... (means over the fold's images), message.
//   summary.json   schema "rephoto.evaluate/1": scene, scheme, folds, failed_folds, missing,
//                  "completeness" and "metrics"/<metric>, each {across_folds, over_images: {mean,
//                  min, q1, median, q3, max, count}, pooled}.
//   projected/<metric>.ply  the `projection_metric` error projected onto the model
//                  (project::ProjectErrors; one model for all folds, else per fold
//                  fold_XX.<metric>.ply when there are several), mesh and point models only.
//   report.html    report::WriteRunReport of the run directory.
//   results.json, per_view.json, metrics.txt (--compat 3dgs) or output.json (--compat
//                  nerfstudio): the numbers papers publish, in the reference tool's own format,
//                  beside per_image.csv's <preset>_<metric> columns and summary.json "compat"
//                  (eval/compat_numbers.h).
//   cache/         file hashes and downscaled photos (safe to delete: only costs time; a sweep
//                  shares SWEEP/cache among its settings instead, EvaluateOptions::cache_dir).
// Outputs of an earlier run with another split (folds, test views) are removed.
//
// The run folder it writes (files, columns, units, schemas): docs/run-folder.md.
#pragma once

#include <cstddef>

#include "rephoto/eval/options.h"

namespace rephoto::eval {

// Runs the evaluation described above and writes the run directory. Throws UsageError for bad
// settings, Error for bad input that stops everything (unreadable scene, another scene's run
// directory, interrupt); failures of single folds or views are recorded, not thrown.
EvaluateResult RunEvaluate(const EvaluateOptions& options);

// Prepares the run folder as a whole run does before its work (inputs, split, fold folders,
// run.json; with the run folder's lock while it does) and lists the tasks of the run: a fold
// task for each fold with a command or a derived model (--colorize, defects), its views in
// chunks of at most `views_per_task`, and "aggregate". Throws as RunEvaluate.
EvaluatePlan PlanEvaluate(const EvaluateOptions& options, size_t views_per_task);

}  // namespace rephoto::eval
