// A run folder has one writer and one owner.
// The run folder contract (files, columns, units): docs/run-folder.md.
//
// Every command that writes a run folder (`compare --out`, `evaluate --out`, `sweep`'s output
// folder) opens it through OpenRunFolder, which
//   1. creates the folder when it does not exist;
//   2. refuses, with a one-line Error, a folder that is not empty and was not made by the same
//      kind of rephoto run ("<dir>: the folder is not empty and holds no rephoto compare run;
//      use an empty or new --out"), or one made by another kind; a folder of the same kind is
//      resumed (evaluate, sweep) or replaced as a whole (compare) by the caller;
//   3. takes an exclusive lock on the file <dir>/.rephoto-run with flock(2), held for as long as
//      the returned RunFolder lives. A second writer gets "<dir>: another rephoto <kind>
//      (pid N) is writing this run folder; wait for it or use another --out" at once instead of
//      waiting. The kernel releases the lock when the process dies, so after `kill -9` the next
//      run starts at once. The descriptor is close-on-exec: the commands a run starts (a
//      reconstruction pipeline) never hold it.
//
// .rephoto-run is also the ownership mark: its first line is "rephoto <kind> run folder" and its
// second the writer's pid. Folders written before the mark existed are recognised by the
// caller's `legacy_owner` test (evaluate: a run.json; compare: only its own output files).
//
// Readers (`report`, `project --errors`) never lock: outputs are renamed into place whole
// (core/file.h), so a reader sees a finished file or none.
//
// Thread safety: a RunFolder is owned by one thread; the lock is per open file description, so
// it also excludes other RunFolders of the same process.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <string_view>

namespace rephoto::run {

// The name of the lock and ownership file inside a run folder.
inline constexpr const char* kRunMarkFile = ".rephoto-run";

class RunFolder {
 public:
  RunFolder() = default;
  RunFolder(RunFolder&& other) noexcept;
  RunFolder& operator=(RunFolder&& other) noexcept;
  RunFolder(const RunFolder&) = delete;
  RunFolder& operator=(const RunFolder&) = delete;
  ~RunFolder();  // releases the lock

  const std::filesystem::path& dir() const { return dir_; }
  bool locked() const { return fd_ >= 0; }

 private:
  friend RunFolder OpenRunFolder(const std::filesystem::path&, std::string_view,
                                 const std::function<bool(const std::filesystem::path&)>&);
  std::filesystem::path dir_;
  int fd_ = -1;
};

// Opens `dir` for writing a run of `kind` ("compare", "evaluate", "sweep"); see above. Throws
// Error naming the folder when it cannot be created, belongs to something else, or is locked.
RunFolder OpenRunFolder(const std::filesystem::path& dir, std::string_view kind,
                        const std::function<bool(const std::filesystem::path&)>& legacy_owner = {});

// True when `dir` has no entries (a missing folder counts as empty).
bool IsEmptyFolder(const std::filesystem::path& dir);

}  // namespace rephoto::run
