// The geometric accuracy of the model(s) a run rendered, against a ground-truth surface: the
// per-run numbers behind the paper's Fig. 8 (1-NCC vs. geometric error over many runs), for
// `rephoto sweep` (a `reference` key) and `rephoto report --reference`.
//
// Which model: an evaluate run rendered one model per fold. For each fold with status "ok" in
// RUN/folds/<fold>/fold.json: the fold's derived model (`colorized_model`, i.e.
// folds/<fold>/model.ply: coloured and/or degraded, exactly what was rendered) when present,
// or, when the fold reused an earlier fold's derived model in memory (same `colorize_key`; it
// then writes no model.ply), that fold's model.ply; else its `model` (a fixed --model, or the
// reconstruction's model; a relative path is taken relative to RUN, then to the current directory).
// A run without fold records falls back to run.json `inputs.model.path`. Compare runs, image-based
// rendering (no model) and unreadable models give an unavailable result with the reason, never an
// exception. Per-fold models are evaluated each (a model file shared by folds, e.g. a fixed --model
// without defects, only once) and the numbers averaged over the folds (arithmetic mean of accuracy
// and of each tolerance's completeness, precision, recall and F-score): every fold's rephoto error
// counts equally in the run's across-fold statistics, so every fold's model counts equally in
// its geometric error. The mean (not the median) keeps a single bad fold's model visible.
//
// Cache: RUN/geometry/<key>.json (schema "rephoto.run_geometry/1"), written atomically; <key> is
// the XXH3 hash of the reference's and every fold model's content and of the options that affect
// the numbers (tolerances, accuracy fraction, samples, seed, crop, transform). A second call with
// unchanged model, reference and options reads it instead of evaluating again. A run folder that
// cannot be written to still gets its result (a warning is logged).
// Units: the reference's. Thread safety: EvaluateRunGeometry may run concurrently on different
// run folders; it is parallel inside (geometry.h).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "rephoto/geometry/geometry.h"

namespace rephoto::geometry {

struct RunModel {
  std::string fold;  // "fold_00", ...; "" for run.json inputs.model
  std::filesystem::path path;
};

struct RunGeometry {
  bool available = false;
  std::string message;  // why not available (one line)
  double accuracy = 0;  // mean over folds; NaN when undefined
  double accuracy_fraction = 0;
  std::vector<ToleranceResult> tolerances;  // means over folds, options.tolerances order
  std::vector<RunModel> models;             // the folds' models (one per fold)
  bool cached = false;                      // read from RUN/geometry/<key>.json
  std::filesystem::path cache_file;
};

// The models the run rendered (see above); empty when it has none (compare runs, image-based
// rendering). Throws Error naming the file when a fold.json or run.json is malformed.
std::vector<RunModel> FindRunModels(const std::filesystem::path& run_dir);

// See the file comment. Throws UsageError for bad options and Error naming the reference when
// it cannot be read; problems of the run's models make the result unavailable instead.
RunGeometry EvaluateRunGeometry(const std::filesystem::path& run_dir,
                                const std::filesystem::path& reference,
                                const GeometryOptions& options);

// Column names for tables ("geo_accuracy", then per tolerance t "geo_completeness@t",
// "geo_precision@t", "geo_recall@t", "geo_f_score@t", t as {:g}) and the values of one result
// in that order (NaN when unavailable).
std::vector<std::string> RunGeometryColumns(const GeometryOptions& options);
std::vector<double> RunGeometryValues(const RunGeometry& result, const GeometryOptions& options);

}  // namespace rephoto::geometry
