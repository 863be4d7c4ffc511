// The benchmark's web pages: server-rendered HTML that works without JavaScript (a small inline
// script only adds sorting by a column header). Every text from the database or a participant
// goes through report::HtmlEscape. Pages link only to other pages and to published files; they
// show aggregates only (nothing per test photo, nothing derived from a photo's pixels).
//   DatasetListPage    /                          the datasets, links to their pages
//   DatasetPage        /datasets/NAME             description, downloads, settings, how to
//                                                 submit with curl, the test images
//   LeaderboardPage    /datasets/NAME/leaderboard the ranking rule, the ranked table (headline
//                                                 filled and mean, completeness, every metric's
//                                                 mean) and the unranked submissions
//   SubmissionPage     /submissions/ID            status, reason, the scores per subset
// Each returns std::nullopt when the dataset or submission does not exist.
// Thread safety: as the Store.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include "rephoto/service/store.h"

namespace rephoto::service {

std::string DatasetListPage(Store& store);
std::optional<std::string> DatasetPage(Store& store, const std::string& name);
std::optional<std::string> LeaderboardPage(Store& store, const std::string& name);
std::optional<std::string> SubmissionPage(Store& store, const std::string& id);
std::string NotFoundPage();

}  // namespace rephoto::service
