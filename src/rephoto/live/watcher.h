// Following a folder while files arrive (copied from a camera, a phone, a drone download).
//
// A file of the watched folder (top level only; sub-folders are not followed) is *ready* when
//   - inotify reports IN_CLOSE_WRITE (the writer closed it) or IN_MOVED_TO (renamed into the
//     folder, the way rsync, browsers and rephoto's own atomic writes finish a file), or
//   - (tools that keep a file open, network file systems without inotify events, files already
//     there at start) its size and modification time have not changed for `stable_seconds`
//     between scans of the folder.
// Names that are temporary by convention are never delivered: a leading '.' or '~', a trailing
// '~', the endings ".part", ".partial", ".tmp", ".crdownload", ".download", ".swp", and names
// containing ".tmp-" (rephoto's own atomic-write temporaries, core/file.h). A ready file is
// delivered once per version (name, size, modification time): rewriting it delivers it again.
//
// Thread safety: a FolderWatcher belongs to one thread.
#pragma once

#include <chrono>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace rephoto::live {

// True for the temporary names above (the file name only, no folder).
bool IsTemporaryName(const std::string& name);

class FolderWatcher {
 public:
  // Throws Error naming the folder when it does not exist or cannot be watched.
  FolderWatcher(const std::filesystem::path& folder, double stable_seconds);
  ~FolderWatcher();
  FolderWatcher(const FolderWatcher&) = delete;
  FolderWatcher& operator=(const FolderWatcher&) = delete;

  // Waits up to `timeout_seconds` for inotify events, scans the folder, and returns the names of
  // the files that became ready, sorted by name. Returns early (possibly empty) on an event.
  std::vector<std::string> Poll(double timeout_seconds);

 private:
  struct Version {
    uintmax_t size = 0;
    std::filesystem::file_time_type mtime;
    bool operator==(const Version&) const = default;
  };
  struct Seen {
    Version version;
    std::chrono::steady_clock::time_point since;  // when this version was first seen
    bool closed = false;                          // an event said the writer finished
  };
  std::filesystem::path folder_;
  double stable_seconds_;
  int fd_ = -1;
  std::map<std::string, Seen> pending_;
  std::map<std::string, Version> delivered_;
};

}  // namespace rephoto::live
