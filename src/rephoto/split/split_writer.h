// Writes a split to disk so that any external pipeline can train on each fold and a renderer
// can render the held-out cameras (`rephoto split`).
//
// Layout under `out_dir` (every file written atomically, core/file.h):
//   split.json                          scheme, seed, folds (see WriteSplit)
//   fold_XX/train.txt, fold_XX/test.txt one image name per line, sorted (names as in the scene,
//                                       relative to its image root)
//   fold_XX/train/sparse/{cameras,images,points3D}.txt   COLMAP text model of the training views
//   fold_XX/train/transforms.json                         the same views as transforms.json
//   fold_XX/test/sparse/{cameras,images,points3D}.txt    the held-out cameras (no points)
//   fold_XX/test/transforms.json
// XX is the fold index, zero-padded to at least two digits (fold_00, fold_01, ...).
// Image paths: COLMAP names stay the scene's names, relative to the scene's image root (an
// absolute path recorded in split.json as "image_root"; pass it as COLMAP's --image_path).
// transforms.json file_path entries point at the original photos, relative to the JSON's folder
// (absolute when no relative path exists), so the outputs move together with the data only if
// their relative position is kept.
// Training points: each 3D point keeps only its observations in training views and is kept if
// at least two remain (it could have been triangulated from training photos alone). Points
// whose format stores no track are dropped: nothing shows they do not depend on test photos.
// With scheme "none" (train = all views) points keep all their observations.
// Intrinsics that transforms.json cannot hold (FOV, THIN_PRISM_FISHEYE, rational FULL_OPENCV)
// skip the transforms.json files with a warning and "transforms_json": false in split.json.
//
// Thread safety: reentrant; concurrent calls must write to different folders.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "rephoto/scene/scene.h"
#include "rephoto/split/split.h"

namespace rephoto::split {

// The sub-scene of the views named in `names` (in the scene's view order): their cameras (ids
// kept) and, if `keep_points`, the points restricted to these views as described above.
// Throws Error when a name is not a view of the scene.
scene::Scene SubsetScene(const scene::Scene& scene, const std::vector<std::string>& names,
                         bool keep_points);

struct SplitSource {
  std::string path;    // the scene path as given
  std::string format;  // its format name
};

// Writes everything described above; returns the fold folders in fold order. Throws Error
// (naming the file) when a file cannot be written.
std::vector<std::filesystem::path> WriteSplit(const scene::Scene& scene, const Split& split,
                                              const SplitSource& source,
                                              const std::filesystem::path& out_dir);

// "fold_00" style folder name for fold `index` of `count`.
std::string FoldFolderName(size_t index, size_t count);

// The test list of a folder WriteSplit wrote, for commands that take one (`compare --split`):
// DIR/test.txt when DIR is a fold folder; DIR/fold_XX/test.txt when DIR is a split folder with
// a single fold (every:N, fraction, lists). Throws Error naming DIR when it holds several folds
// (the message names them: pass one fold's folder) or is neither.
std::filesystem::path SplitTestList(const std::filesystem::path& dir);

}  // namespace rephoto::split
