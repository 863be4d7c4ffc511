// Image names inside scene files, and the names of the files rephoto writes for each view.
//
// Every name a scene file gives for an image (COLMAP images.txt/.bin, transforms.json
// file_path/mask_path, Bundler list.txt, Middlebury *_par.txt, ...) is hostile until checked:
// it is joined to the image root to read a photo, and to folders of a run to write links,
// renders and error images. The rule, applied by every reader where it takes the name (so no
// later stage can see a bad one) and again by ValidateScene:
//
//   A name is a relative path below the image root, '/'-separated. Harmless spellings that
//   formats write routinely are normalised: "." components ("./train/r_0.png", NeRF-synthetic)
//   and repeated '/' are dropped. Refused with a one-line Error
//   "<file>:<line>: image name '<name>' <why>" are: an empty name, an absolute path ('/' first),
//   any ".." component (even one that would stay inside the root: names are keys, and
//   "a/../b.png" and "b.png" must not be two views of one photo), a backslash (a separator on
//   Windows, where the same scene may be read), a name ending in '/', and control characters
//   (bytes below 0x20 and 0x7f: they break CSV rows and log lines).
//
// The rule is lexical: a symbolic link inside the image root that points elsewhere is the
// user's own choice and is followed when reading photos; rephoto never writes through one it
// did not make (run folders are created by rephoto).
//
// Thread safety: pure functions.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "rephoto/scene/scene.h"

namespace rephoto::scene {

// The name in normal form, or throws Error "<where>: image name '<raw>' <why>" (see above).
std::string CheckedImageName(std::string_view raw, std::string_view where);

// Indices into scene.views of the views named in `names`, in that order (names from a list file
// or an option; checked and normalised by the rule above first). Throws Error "<source>: image
// '<name>' is not in the scene" for a name no view has.
std::vector<size_t> ViewIndices(const Scene& scene, const std::vector<std::string>& names,
                                std::string_view source);

// The stems under which rephoto writes a view's files (renders/<stem>.png, errors/<stem>.*),
// one per view in scene order, distinct within the scene:
//   - the file name without extension ("images/a.jpg" -> "a") when those are distinct;
//   - else the relative path without extension for every view ("cam0/a.jpg" -> "cam0/a"), so
//     rigs whose cameras number their frames alike keep one file per view;
//   - else (two views differ only in extension: "a.jpg", "a.png") the whole name for every view
//     ("a.jpg" -> stem "a.jpg", rendered as "a.jpg.png").
// A stem with a '/' names a file in a subfolder, which writers create.
std::vector<std::string> OutputStems(const Scene& scene);

}  // namespace rephoto::scene
