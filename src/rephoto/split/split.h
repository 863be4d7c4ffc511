// Training/evaluation splits of a scene's photos (paper Sections 3.1 and 4.4): which photos a
// reconstruction may use, and at which held-out cameras it is rephotographed.
//
// Schemes (the text form is what `rephoto split --scheme` takes):
//   kfold:K[:SEED]    K-fold cross-validation: the names, sorted, are shuffled with SEED
//                     (default 0; SeededShuffle, identical on every machine) and the i-th
//                     shuffled name goes to the test set of fold i mod K. Folds are disjoint,
//                     every image is tested exactly once, test sizes differ by at most 1.
//                     2 <= K <= number of images. The shuffle may put neighbouring photos
//                     of a capture path into one fold (with 8 photos, fold 0 may hold out
//                     3 neighbours, leaving a hole in its training set); interleaved:K avoids
//                     that.
//   interleaved:K     K folds without a shuffle: sorted by name (the capture order of most
//                     cameras' file names), image i goes to the test set of fold i mod K, so
//                     neighbours are tested in different folds and every training set keeps
//                     photos on both sides of each test photo. 2 <= K <= number of images.
//   loo               leave-one-out: one fold per image (sorted by name), testing that image.
//   every:N           one fold; sorted by name, image i is a test image iff i % N == 0 (index
//                     0 is a test image). This is the "llffhold" convention of mip-NeRF 360 /
//                     multinerf (internal/datasets.py: test = all_indices % llffhold == 0 with
//                     load_alphabetical sorting by name) and 3D Gaussian splatting
//                     (scene/dataset_readers.py: cameras sorted by image name, test if
//                     idx % llffhold == 0); every:8 reproduces their test sets. N >= 2.
//   fraction:F[:SEED] one fold; round(F * n) (half away from zero) images (at least 1, at most n -
//   1) chosen by the
//                     seeded shuffle of the sorted names are test images. 0 < F < 1.
//   lists:TRAIN,TEST  one fold from two text files with one image name per line (blank lines
//                     and lines starting with '#' ignored). Every name must be in the scene and
//                     in at most one list; images in neither list are unused.
//   none              one fold with train = test = all images, for methods that cannot hold
//                     out photos; flagged as not cross-validated (the error is then a fit
//                     error, not a prediction error).
// Names are compared byte-wise (std::string operator<), the order Python's sorted() gives.
//
// Thread safety: pure functions (ParseScheme, MakeSplit read only their arguments and the list
// files named).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace rephoto::split {

enum class SchemeKind { kKFold, kInterleaved, kLeaveOneOut, kEveryNth, kFraction, kLists, kNone };

struct Scheme {
  SchemeKind kind = SchemeKind::kNone;
  int folds = 0;                     // kKFold: K
  int every = 0;                     // kEveryNth: N
  double fraction = 0.0;             // kFraction: F
  uint64_t seed = 0;                 // kKFold, kFraction
  std::filesystem::path train_list;  // kLists
  std::filesystem::path test_list;   // kLists

  // Canonical text form, e.g. "kfold:5:0", "every:8", "fraction:0.2:7", "lists:a.txt,b.txt".
  std::string ToString() const;
  // Scheme name without parameters: "kfold", "loo", "every", "fraction", "lists", "none".
  std::string_view Name() const;
  // Whether the schemes uses a seed.
  bool Seeded() const { return kind == SchemeKind::kKFold || kind == SchemeKind::kFraction; }
};

// Parses the text form above. Throws rephoto::UsageError "--scheme '<text>': ..." on bad syntax or
// out-of-range parameters.
Scheme ParseScheme(std::string_view text);

struct Fold {
  std::vector<std::string> train;  // sorted by name
  std::vector<std::string> test;   // sorted by name
};

struct Split {
  Scheme scheme;
  std::vector<Fold> folds;
  // false only for "none": training and test images are the same.
  bool cross_validated = true;
};

// Splits `image_names` (unique; any order) by `scheme`. For kLists the list files are read
// here. Throws Error when the scheme does not fit the number of images (e.g. K > n), a name
// is duplicated, or a list names an unknown image ("<list>:<line>: ...").
Split MakeSplit(const std::vector<std::string>& image_names, const Scheme& scheme);

// Reads a list file (one image name per line; blank and '#' lines ignored; "./" prefixes
// dropped). Throws Error naming the file when it cannot be read. The names are not checked
// here: callers check them (scene::CheckedImageName / ViewIndices) with the location.
std::vector<std::string> ReadImageList(const std::filesystem::path& path);

// One name of a list file and its line (1-based), for messages "<file>:<line>: ...".
struct ImageListEntry {
  std::string name;
  int line = 0;
};

// ReadImageList with the line of each name.
std::vector<ImageListEntry> ReadImageListEntries(const std::filesystem::path& path);

}  // namespace rephoto::split
