// The JSON documents of the public API (docs/benchmark.md), built from the Store. The HTTP
// layer (server.h) and the pages (pages.h) only format what these return.
// Nothing here reads a file below <root>/secret, no path on the server is returned, and nothing
// derived pixel by pixel from a secret photo exists (no error images are made).
// Numbers: NaN is null, infinities "inf"/"-inf", as in summary.json (docs/run-folder.md).
// Thread safety: as the Store (safe from any thread).
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "rephoto/service/store.h"

namespace rephoto::service {

// GET /api/datasets: [{name, description, training_images, test_images, files: [...]}]
nlohmann::json DatasetListJson(Store& store);

// GET /api/datasets/NAME: name, description, scheme, settings, training_images and
// test_images ([{name, stem, width, height}]), shortcuts, files ([{name, url, size}]).
std::optional<nlohmann::json> DatasetJson(Store& store, const std::string& name);

// How a dataset's leaderboard ranks (settings "ranking", `add-dataset --ranking`):
//   "filled" (the default): by the headline metric's filled score (ComputeScores in
//     submissions.h: every pixel not rendered counts at the metric's worst value);
//   "min-completeness:F": by the headline metric's mean over the covered pixels, among the
//     submissions whose completeness (over the photos ranked) is at least F; the others are
//     listed apart, unranked.
// Either way rendering less never buys a better rank.
struct RankingRule {
  std::string text;                        // as given ("filled", "min-completeness:0.9")
  std::optional<double> min_completeness;  // set for min-completeness:F
};
// Throws UsageError for anything else.
RankingRule ParseRankingRule(const std::string& text);
// The rule in one sentence, as every leaderboard states it.
std::string RankingRuleText(const RankingRule& rule, const std::string& headline);
RankingRule DatasetRankingRule(const DatasetRecord& dataset);

// How many test photos a subset has: "all", "public" (all without a split), "private".
size_t TestPhotoCount(const DatasetRecord& dataset, const std::string& subset);

struct LeaderboardOptions {
  // false: only the best submission of each participant and method; true: every submission.
  bool all_submissions = false;
};

// GET /api/datasets/NAME/leaderboard[?all=1]: {dataset, headline, higher_is_better,
// ranking: {rule, text}, photos: {subset, count}, revealed, best_per_method,
// entries: [{rank, id, participant, method, description, created,
//            headline: {mean, filled}, completeness, metrics: {<name>: mean}, filled: {...},
//            public (after the reveal)}],
// unranked: [the same without rank: below the minimum completeness]}
// Only done submissions with scores. The photos ranked: all test photos without a split; with
// one the public photos until `rephoto benchmark reveal`, then the private ones. Aggregates
// only: nothing per photo.
std::optional<nlohmann::json> LeaderboardJson(Store& store, const std::string& name,
                                              const LeaderboardOptions& options = {});

// GET /api/submissions/ID: {id, dataset, participant, method, description, status, reason,
// created}; when done "scores" (ComputeScores per subset: "all" and "private" only after the
// reveal), "summary" (summary.json without the server's paths) and
// "completeness_over_test_photos" (without a split or after the reveal). "images" (per_image.csv
// rows as objects without paths; of the public photos only until the reveal) only when
// `viewer` is the submission's own participant.
std::optional<nlohmann::json> SubmissionJson(Store& store, const std::string& id,
                                             const std::optional<ParticipantRecord>& viewer = {});

// GET /api/participants/me/submissions (token): {participant, quota, submissions: [{id,
// dataset, method, status, created, url}]}, newest first.
nlohmann::json ParticipantSubmissionsJson(Store& store, const ParticipantRecord& participant,
                                          const nlohmann::json& quota);

// summary.json without the server's paths (parameters photos, renders, render_masks,
// photo_masks).
nlohmann::json PublicSummary(const nlohmann::json& summary);

// The JSON text of a response: invalid UTF-8 in stored text is replaced (U+FFFD), never thrown.
std::string JsonText(const nlohmann::json& json, int indent = 2);

// The JSON value of a summary number (null, "inf", "-inf" or a number) as a double.
double JsonNumber(const nlohmann::json& value);

}  // namespace rephoto::service
