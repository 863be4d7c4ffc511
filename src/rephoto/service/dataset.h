// Turning a calibrated scene into a benchmark dataset (`rephoto benchmark add-dataset`).
//
// The scene's photos are split by a one-fold scheme (split/split.h: every:N, fraction:F,
// lists:TRAIN,TEST). Under the root folder:
//   public/<name>/training.tar      training photos (images/<scene name>), their cameras as
//                                   COLMAP text (sparse/cameras.txt, images.txt, points3D.txt;
//                                   points seen by at least two training photos) and
//                                   transforms.json (file_path images/<scene name>)
//   public/<name>/test-cameras.tar  the test cameras only: sparse/*.txt (no points),
//                                   transforms.json, test_images.txt (one stem per line: the
//                                   names the renders must have); never a test photo
//   public/<name>/shortcuts.tar     the --shortcut files and folders (shortcuts/<base name>/...)
//   secret/<name>/photos/<stem><ext>  the test photos, for scoring only (<stem>.png when
//                                   downscaled for eval_short_side)
//   secret/<name>/masks/<stem>.png  their masks, when the dataset has masks
// The tar files are recorded in the database (Store::AddDataset), and the server serves a file
// only through that record; nothing under secret/ is ever recorded.
// Test-image stems are the scene's output stems (scene/image_name.h OutputStems); a scene whose
// test stems need subfolders is refused (renders are uploaded as one flat folder).
// Evaluation settings are fixed per dataset and recorded in DatasetRecord::info["settings"]:
// metrics, the headline metric (leaderboard order), the metric window, eval_short_side and
// whether photo masks apply ("masks"), the ranking rule ("ranking") and the public test photos
// ("public_stems", with a split).
// Failure: throws Error (UsageError for bad settings); a failure leaves no dataset behind
// (files are staged in hidden folders and the database row is written last).
// Thread safety: not for concurrent calls with the same name.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "rephoto/service/store.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/scene/read_scene.h"

namespace rephoto::service {

struct DatasetOptions {
  std::string name;  // [A-Za-z0-9_.-], 1..64 bytes, not starting with '.'
  std::string description;
  std::filesystem::path scene;
  scene::ReadSceneOptions read_options;
  std::string scheme;  // a one-fold split scheme
  std::vector<std::filesystem::path> shortcuts;
  std::vector<metrics::Metric> metrics = metrics::AllMetrics();
  std::string headline = "1-ncc";  // must be one of `metrics`
  // > 0: the test photos are compared at the size whose shorter side is this (never upscaled):
  // the published test cameras are scaled (Camera::Scaled) and the secret photos (and masks,
  // conservatively) downscaled once with the area filter (compare/resample.h) to 16-bit PNG.
  int eval_short_side = 0;
  // Photo masks of the test photos (0 = ignore the pixel: sky, people): the views' own mask
  // files (transforms.json mask_path) or, when set, the images of this folder by stem. Either
  // every test photo has a mask or none.
  std::filesystem::path photo_masks;
  int window = 9;  // metric and completeness window (odd, 3..101), compare's default
  // The leaderboard's ranking rule (api.h RankingRule): "filled" or "min-completeness:F".
  std::string ranking = "filled";
  // < 1: a public/private split of the test photos: this fraction of them, chosen at random
  // and kept secret (settings "public_stems"), ranks the leaderboard until `rephoto benchmark
  // reveal`; the others are scored but shown only after it.
  double public_fraction = 1;
};

// `rephoto benchmark reveal`: the dataset's private test photos' scores become public and rank
// its leaderboard (info "revealed"). Throws Error for an unknown dataset.
void RevealDataset(Store& store, const std::string& name);

// Throws UsageError unless `name` is a valid dataset name (see DatasetOptions::name).
void CheckDatasetName(const std::string& name);

// Adds the dataset (see above) and returns its database id.
int64_t AddDataset(Store& store, const DatasetOptions& options);

// Where the secret test photos of a dataset are.
std::filesystem::path SecretPhotoFolder(const std::filesystem::path& root, const std::string& name);
std::filesystem::path SecretMaskFolder(const std::filesystem::path& root, const std::string& name);

}  // namespace rephoto::service
