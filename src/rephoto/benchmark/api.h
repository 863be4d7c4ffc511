// The JSON documents of the public API (docs/benchmark.md), built from the Store. The HTTP
// layer (server.h) and the pages (pages.h) only format what these return.
// Nothing here reads a file below <root>/secret, and no path on the server is returned except
// inside a submission's summary (compare's summary.json "parameters", verbatim).
// Numbers: NaN is null, infinities "inf"/"-inf", as in summary.json (docs/run-folder.md).
// Thread safety: as the Store (safe from any thread).
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "rephoto/benchmark/store.h"

namespace rephoto::benchmark {

// GET /api/datasets: [{name, description, training_images, test_images, files: [...]}]
nlohmann::json DatasetListJson(Store& store);

// GET /api/datasets/NAME: name, description, scheme, settings, training_images and
// test_images ([{name, stem, width, height}]), shortcuts, files ([{name, url, size}]).
std::optional<nlohmann::json> DatasetJson(Store& store, const std::string& name);

// GET /api/datasets/NAME/leaderboard: {dataset, headline, higher_is_better, entries: [{rank,
// id, participant, method, description, created, headline: {mean, median}, completeness,
// metrics: {<name>: mean over images}}]}
// ordered by the headline metric's mean over images (best first; no value last), only
// submissions that are done. completeness is LeaderboardCompleteness (over all test photos).
std::optional<nlohmann::json> LeaderboardJson(Store& store, const std::string& name);

// GET /api/submissions/ID: {id, dataset, participant, method, description, status, reason,
// created} and when done "summary" (summary.json) and "images" (per_image.csv rows as objects
// without the photo and render paths; empty fields null, numbers as numbers).
std::optional<nlohmann::json> SubmissionJson(Store& store, const std::string& id);

// The JSON value of a summary number (null, "inf", "-inf" or a number) as a double.
double JsonNumber(const nlohmann::json& value);

}  // namespace rephoto::benchmark
