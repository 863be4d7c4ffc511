// `rephoto sweep CONFIG`: `rephoto evaluate` over a grid of settings (paper Section 4: synthetic
// defects, Fig. 5/6; training-set size |T| and training resolution, Fig. 7), one combined table
// and one report with error vs. setting as boxplots across folds.
//
// Config file (TOML .toml or JSON .json): the top level holds the experiment exactly as
// `rephoto evaluate --config` reads it (eval/settings.h: scene, scheme, reconstruct, model,
// colorize, metrics, eval_short_side, ...; relative paths are relative to the config file),
// plus one table "sweep":
//   [sweep]
//   train_count = "halve"          # or a list of sizes; "halve" = the paper's series: the
//                                  # smallest fold's training-set size, halved repeatedly
//   min_train_count = 2            # where "halve" stops (default 2)
//   train_short_side = [1024, 512] # any parameter of sweep/grid.h as a list of numbers:
//   texture_noise = [0, 0.1, 0.2]  #   texture_noise, geometry_noise, simplify, seed,
//                                  #   train_count, train_short_side
//   x = "train_count"              # the plots' x axis (default: the last axis, see below)
//   out = "sweep_out"              # the sweep's folder (or --out; default "<config stem>.sweep")
//   reference = "gt.ply"           # optional ground-truth surface (paper Fig. 8): each setting's
//                                  # rendered model(s) against it (geometry/run_geometry.h);
//                                  # sweep.csv gains geo_* columns, report.html the geometric
//                                  # columns, 1-NCC vs. accuracy scatterplot and correlations
//   tolerances = [0.001, 0.002]    # with reference: distance thresholds (reference units)
//   accuracy_fraction = 0.9        # with reference: Middlebury accuracy fraction
//   geometry_samples = 1000000     # with reference: area-uniform samples per surface
// The geometric keys live in [sweep] (not at the top level, which is `rephoto evaluate`'s
// config and rejects keys it does not know); `reference` is relative to the config file.
// Config tables have no order, so the axes are taken by name, except the x axis, which comes
// last and so varies fastest; the other axes' combinations are the series of the plots.
//
// What a setting changes in the evaluation: train_count and train_short_side set the
// evaluate options of the same names (every fold's pipeline gets fewer or smaller training
// photos; rephotos are always rendered and compared at the one evaluation resolution,
// eval_short_side); texture_noise, geometry_noise, simplify and seed degrade each fold's model
// after it was reconstructed (and coloured), before it is rendered (degrade/degrade.h; only
// for models rendered by rephoto, not with an external renderer).
//
// Output folder:
//   settings/<setting name>/   one evaluate run directory per setting (eval/evaluate.h)
//   sweep.csv, sweep_per_fold.csv   the combined tables (sweep/table.h)
//   sweep.json     schema "rephoto.sweep/1": the axes, x axis, each setting's folder, status and
//                  timings, and the time split into the external pipeline and rephoto's own
//                  work (split, render, compare, aggregate, ...) with rephoto's share
//   report.html    report::WriteCollectionReport: one series per combination of the other axes
// --executor slurm (base.executor, base.slurm; a [slurm] table of the config file holds the
// cluster/slurm_settings.h resources): every setting's tasks (eval/slurm_executor.h) go into one
// set of job arrays, followed by one job that writes the sweep's tables, report and sweep.json
// (`rephoto sweep CONFIG --out OUT --only-aggregate`); docs/cluster.md.
// Settings are independent tasks; each is an evaluate run and resumes like one, so rerunning
// the same command skips everything already done. A setting whose evaluation fails is recorded
// and the others go on (exit code kIncomplete).
//
// Thread safety: LoadSweepConfig* are reentrant. RunSweep is a whole run: it owns its output folder
// (one writer per folder, run/run_folder.h) and reads the process-wide interrupt flag; run at most
// one per folder.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/core/error.h"
#include "rephoto/cluster/slurm.h"
#include "rephoto/eval/evaluate.h"
#include "rephoto/geometry/geometry.h"
#include "rephoto/sweep/grid.h"
#include "rephoto/sweep/table.h"

namespace rephoto::sweep {

struct SweepOptions {
  eval::EvaluateOptions base;  // the experiment; base.out is ignored
  std::vector<SweepAxis> axes;
  bool halve_train_count = false;  // train_count = "halve": its values are computed at run time
  int min_train_count = 2;
  std::string x_axis;  // "" = the last axis
  std::filesystem::path out;
  bool report = true;
  std::filesystem::path reference;     // "" = no geometric evaluation
  geometry::GeometryOptions geometry;  // with `reference`
  // Only the sweep's own aggregation (tables, report, sweep.json) from the settings' run folders,
  // without evaluating and without the sweep folder's lock: the last task of a sweep on Slurm.
  bool only_aggregate = false;
};

struct SettingOutcome {
  SweepSetting setting;
  std::filesystem::path run_dir;
  bool ok = true;
  std::string message;  // when the whole evaluation of the setting failed
  eval::EvaluateResult result;
};

struct SweepResult {
  std::vector<SweepAxis> axes;  // with "halve" resolved
  std::vector<SettingOutcome> settings;
  SweepTable table;
  double total_seconds = 0;
  double external_seconds = 0;  // the pipelines' commands
  double rephoto_seconds = 0;   // rephoto's own work inside the evaluations
  // CPU seconds (eval::EvaluateTimings::external_cpu / rephoto_cpu summed over the settings):
  // the share that does not depend on overlap or on other load on the machine.
  double external_cpu_seconds = 0, rephoto_cpu_seconds = 0;
  ExitCode exit_code = ExitCode::kOk;
  // --executor slurm (base.executor): what became of the submitted tasks, and whether they all
  // finished (false after --no-wait); the tables are then written by the "sweep" task.
  cluster::RunOutcome slurm;
  bool slurm_finished = false;
  // rephoto's fraction of the accounted wall-clock seconds and of the CPU seconds (0 if none).
  double rephoto_share() const { return eval::RephotoShare(rephoto_seconds, external_seconds); }
  double rephoto_cpu_share() const {
    return eval::RephotoShare(rephoto_cpu_seconds, external_cpu_seconds);
  }
};

// Reads a sweep config file (see above). Throws Error naming the file and key.
SweepOptions LoadSweepConfig(const std::filesystem::path& file);
// The same from the file's text (tests, fuzzers); `file` as for eval::LoadConfigText.
SweepOptions LoadSweepConfigText(std::string_view text, const std::filesystem::path& file);

// Runs the sweep and writes the outputs. Throws Error for bad settings; a failing setting is
// recorded, not thrown.
SweepResult RunSweep(const SweepOptions& options);

}  // namespace rephoto::sweep
