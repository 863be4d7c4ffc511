// The report of `rephoto suggest` (acquisition guidance, paper Sections 5.2 and 6.2): one
// self-contained HTML page showing the suggested camera poses for the next photos.
//
// Reads DIR/suggestions.json (written by `rephoto suggest`: per suggestion name, centre, qvec,
// tvec, score, unobserved_area, visible_vertices, mean_error; and the totals total_area,
// unobserved_area, unobserved_area_covered) and the rephotos DIR/renders/<name>. Shows the
// totals (the share of the model's surface that no photo sees, in model units² and %, and how
// much of it the suggestions see together) and, per suggestion, its rephoto (what to
// photograph), "camera at (x, y, z) looking at (x, y, z)" in the scene's units (COLMAP qvec and
// tvec below it), the unseen surface it newly covers (model units², % of the unseen surface
// and % of the whole surface), the number of vertices it sees and the mean projected error it
// looks at ("–" when the suggestions were made without projected errors: `rephoto suggest`
// without --run). suggestions.json must say "schema": "rephoto.suggest/1" (or, written
// before the rename, "version": 1).
// Failure behaviour: a missing or malformed suggestions.json throws Error naming it; a name in it
// that is not a plain file name (a path, "..") throws Error naming the file (nothing outside
// DIR/renders is read); a missing rephoto only replaces that image by the reason. The page is
// written atomically. Thread safety: reentrant.
#pragma once

#include <filesystem>
#include <string>

#include "rephoto/report/view3d.h"

namespace rephoto::suggest {

// DIR/suggestions.json + DIR/renders/ -> `out_html` (usually DIR/report.html), with the 3D
// view `view` (report/view3d.h: the model, the photos and the suggested views) when given.
void WriteSuggestionsReport(const std::filesystem::path& dir, const std::filesystem::path& out_html,
                            int thumbnail_width = 480, const report::View3dData* view = nullptr);

// The body of that page (the inputs' names, the coverage and the table of suggested views) for
// another page to embed (the demo's comparison report: CollectionOptions::suggestions), with
// headings <h`heading_level`>.
std::string SuggestionsSectionHtml(const std::filesystem::path& dir, int thumbnail_width,
                                   int heading_level);

}  // namespace rephoto::suggest
