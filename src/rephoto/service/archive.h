// Reading submitted archives and writing the tar files a dataset publishes (libarchive).
//
// ExtractRenders reads a .tar (optionally gzip-compressed) or .zip from memory or a file, entry
// by entry, and writes nothing but regular files named <stem><ext> directly inside `out_dir`:
//   - directory entries are skipped; every other entry must be a regular file: a symbolic or
//     hard link, device, FIFO or socket is refused (400);
//   - the entry's name must pass scene::CheckedImageName (no "..", no absolute path, no
//     backslash or control character: 400); its last component must end in .png, .jpg, .jpeg
//     or .exr (any case) and its stem must be one of `stems` (the test images), once (400);
//   - more than `limits.max_files` entries (of any type), or more than `limits.max_bytes` extracted
//     bytes in total, stop the extraction at once (413): the count runs while data is copied,
//     so a bomb that declares a small size is stopped by what it really inflates to;
//   - a malformed or unsupported archive is refused (400) with libarchive's reason.
// Files are opened with O_CREAT | O_EXCL | O_NOFOLLOW inside `out_dir`, which must be an empty
// folder the caller made; libarchive's disk writer is never used. On any refusal the files
// written so far stay in `out_dir` for the caller to remove (it owns the folder).
// Failure: throws Refused with the HTTP status and a one-line reason naming the entry.
// Thread safety: pure functions (each call its own libarchive handle).
#pragma once

#include <cstdint>
#include <filesystem>
#include <set>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "rephoto/core/error.h"

namespace rephoto::service {

// A request refused with an HTTP status (400, 404, 413, 429) and a one-line reason.
class Refused : public Error {
 public:
  Refused(int status, const std::string& message) : Error(message), status(status) {}
  int status;
};

struct ArchiveLimits {
  int64_t max_bytes = int64_t{2} << 30;  // extracted bytes, all entries together
  size_t max_files = 10000;              // entries of any type (folders too)
};

struct ExtractedFile {
  std::string stem;
  std::filesystem::path path;  // out_dir / (stem + lower-case extension)
  int64_t size = 0;
};

// See above. Returns the files sorted by stem. Entry names that are not clean text (text.h:
// invalid UTF-8, control characters) are refused (400); messages show names by Printable.
std::vector<ExtractedFile> ExtractRenders(std::string_view archive,
                                          const std::set<std::string>& stems,
                                          const ArchiveLimits& limits,
                                          const std::filesystem::path& out_dir);
// The same, reading the archive from a file (an upload streamed to disk), 64 KiB at a time.
std::vector<ExtractedFile> ExtractRendersFromFile(const std::filesystem::path& archive,
                                                  const std::set<std::string>& stems,
                                                  const ArchiveLimits& limits,
                                                  const std::filesystem::path& out_dir);

struct TarMember {
  std::string name;              // the name inside the archive ('/'-separated, relative)
  std::filesystem::path source;  // a regular file to copy
};

// Writes an uncompressed POSIX (pax) tar of `members` to `path` atomically (core/file.h).
// Throws Error naming the file that cannot be read or written.
void WriteTar(const std::filesystem::path& path, const std::vector<TarMember>& members);

}  // namespace rephoto::service
