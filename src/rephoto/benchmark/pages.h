// The benchmark's web pages: server-rendered HTML that works without JavaScript (a small inline
// script only adds sorting by a column header). Every text from the database or a participant
// goes through report::HtmlEscape. Pages link only to other pages, to published files and to a
// submission's error images (never to a photo: the secret test photos are not reachable).
//   DatasetListPage    /                          the datasets, links to their pages
//   DatasetPage        /datasets/NAME             description, downloads, settings, how to
//                                                 submit with curl, the test images
//   LeaderboardPage    /datasets/NAME/leaderboard ranked table (headline metric, completeness
//                                                 over all test photos, every metric's mean)
//                                                 and boxplots of the per-image headline values
//   SubmissionPage     /submissions/ID            status, summary, per-image table with the
//                                                 error images (jet colours) of the headline
//                                                 metric: errors of what the submitter uploaded
// Each returns std::nullopt when the dataset or submission does not exist.
// Thread safety: as the Store.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include "rephoto/benchmark/store.h"

namespace rephoto::benchmark {

std::string DatasetListPage(Store& store);
std::optional<std::string> DatasetPage(Store& store, const std::string& name);
std::optional<std::string> LeaderboardPage(Store& store, const std::string& name);
std::optional<std::string> SubmissionPage(Store& store, const std::string& id);
std::string NotFoundPage();

// The error PNG "<stem>.<metric>" of a done submission, when id, stem and metric are those of
// the submission and its dataset and the file exists; else std::nullopt.
std::optional<std::filesystem::path> ErrorImagePath(Store& store, const std::string& id,
                                                    const std::string& stem_and_metric);

}  // namespace rephoto::benchmark
