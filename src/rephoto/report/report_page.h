// Internal building blocks of report.cc (HTML fragments of one run), shared by the run and
// the collection report. Not part of the public API.
//
// Thread safety: pure functions of the run::RunData given (ExamplesHtml also reads the images it names).
#pragma once

#include <string>

#include "rephoto/run/run_data.h"

namespace rephoto::report::internal {

// The page skeleton: <!DOCTYPE html> ... <body>, with the inline CSS and the error hook.
std::string PageStart(const std::string& title);
// The inline script (sortable tables, #sort= hook, data-ready) and </body></html>.
std::string PageEnd();

// Key facts and the flattened settings table (collapsed when `collapsed`).
std::string SettingsHtml(const run::RunData& run, bool collapsed);
// Failed folds with messages and missing/failed images ("" when there are none).
std::string ProblemsHtml(const run::RunData& run);
// The summary table(s): across folds (when run::RunData::AcrossFolds) and over images.
std::string SummaryHtml(const run::RunData& run);
// The per-fold table of an evaluate run (class "sortable", id "per-fold"); "" for compare runs.
std::string PerFoldTableHtml(const run::RunData& run);
// The per-image table (class "sortable", id `table_id`).
std::string PerImageTableHtml(const run::RunData& run, const std::string& table_id);
// The `count` worst and best images by metric `metric` (index into run.metrics).
std::string ExamplesHtml(const run::RunData& run, int metric, int count, int thumbnail_width);

}  // namespace rephoto::report::internal
