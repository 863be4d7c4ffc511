// Fuzzes the upload path of `rephoto serve` (src/rephoto/service/archive.h and the image
// checks of submissions.cc): the input is an uploaded archive, extracted by ExtractRenders on
// the real libarchive (tar, tar.gz, zip) with its per-entry checks (regular files only, clean
// names, no "..", render extensions, test stems "00" and "03" once each, at most 64 entries and
// 4 MiB extracted) into a scratch folder, then each render's header is read as the server reads
// it to compare its size with the test camera's. Accepted outcomes: files, or a Refused / Error.
// Invariants: every extracted file lies directly in the scratch folder, is named
// <stem><lower-case extension> and nothing else is there; the total size respects the limit.
#include <unistd.h>

#include <cstdlib>
#include <filesystem>

#include "fuzz_common.h"
#include "rephoto/service/archive.h"
#include "rephoto/io/image_io.h"

namespace fs = std::filesystem;

namespace {

// The scratch folder, made once and removed when the process exits normally (libFuzzer ends
// a timed run with exit(); after a crash it stays, with the input that caused it).
struct ScratchFolder {
  fs::path path;
  ScratchFolder() {
    char pattern[] = "/tmp/rephoto-fuzz-upload-XXXXXX";
    const char* made = mkdtemp(pattern);
    if (!made) std::abort();
    path = made;
  }
  ~ScratchFolder() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

const fs::path& Scratch() {
  static const ScratchFolder folder;
  return folder.path;
}

void Check(bool condition, const char* what) {
  if (!condition) {
    std::fprintf(stderr, "invariant broken: %s\n", what);
    std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const fs::path& out = Scratch();
  fs::remove_all(out);
  fs::create_directories(out);
  rephoto::service::ArchiveLimits limits;
  limits.max_bytes = 4 << 20;
  limits.max_files = 64;
  rephoto::fuzz::AcceptsInput([&] {
    const auto files = rephoto::service::ExtractRenders(rephoto::fuzz::AsText(data, size),
                                                          {"00", "03"}, limits, out);
    int64_t total = 0;
    for (const auto& file : files) {
      Check(file.path.parent_path() == out, "a render outside the scratch folder");
      Check(file.stem == "00" || file.stem == "03", "a render of an unknown stem");
      total += file.size;
      rephoto::io::ReadImageHeader(file.path);  // the server's size check reads this
    }
    Check(total <= limits.max_bytes, "more extracted than the limit");
    size_t entries = 0;
    for (const auto& entry : fs::directory_iterator(out)) {
      Check(entry.is_regular_file() && !entry.is_symlink(), "not a regular file extracted");
      ++entries;
    }
    Check(entries == files.size(), "files extracted that were not reported");
  });
  return 0;
}
