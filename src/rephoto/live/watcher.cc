#include "rephoto/live/watcher.h"

#include <poll.h>
#include <sys/inotify.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <set>

#include "rephoto/core/error.h"

namespace rephoto::live {
namespace fs = std::filesystem;

bool IsTemporaryName(const std::string& name) {
  if (name.empty() || name[0] == '.' || name[0] == '~' || name.back() == '~') return true;
  for (const char* end : {".part", ".partial", ".tmp", ".crdownload", ".download", ".swp"}) {
    const size_t n = std::strlen(end);
    if (name.size() >= n && name.compare(name.size() - n, n, end) == 0) return true;
  }
  return name.find(".tmp-") != std::string::npos;
}

FolderWatcher::FolderWatcher(const fs::path& folder, double stable_seconds)
    : folder_(folder), stable_seconds_(stable_seconds) {
  std::error_code ec;
  REPHOTO_CHECK(fs::is_directory(folder, ec), "{}: not a folder", folder.string());
  fd_ = inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
  REPHOTO_CHECK(fd_ >= 0, "{}: cannot watch: {}", folder.string(), std::strerror(errno));
  if (inotify_add_watch(fd_, folder.c_str(), IN_CLOSE_WRITE | IN_MOVED_TO | IN_MODIFY | IN_CREATE) <
      0) {
    const int e = errno;
    close(fd_);
    fd_ = -1;
    throw Error(fmt::format("{}: cannot watch: {}", folder.string(), std::strerror(e)));
  }
}

FolderWatcher::~FolderWatcher() {
  if (fd_ >= 0) close(fd_);
}

std::vector<std::string> FolderWatcher::Poll(double timeout_seconds) {
  std::set<std::string> closed;
  pollfd p{fd_, POLLIN, 0};
  const int ms = static_cast<int>(std::max(0.0, timeout_seconds) * 1000);
  if (poll(&p, 1, ms) > 0) {
    alignas(inotify_event) char buffer[16384];
    for (;;) {
      const ssize_t n = read(fd_, buffer, sizeof(buffer));
      if (n <= 0) break;
      for (ssize_t at = 0; at < n;) {
        const auto* e = reinterpret_cast<const inotify_event*>(buffer + at);
        if (e->len > 0 && (e->mask & (IN_CLOSE_WRITE | IN_MOVED_TO))) closed.insert(e->name);
        at += static_cast<ssize_t>(sizeof(inotify_event) + e->len);
      }
    }
  }
  const auto now = std::chrono::steady_clock::now();
  std::vector<std::string> ready;
  std::set<std::string> present;
  std::error_code ec;
  for (fs::directory_iterator it(folder_, ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    std::error_code ec2;
    if (IsTemporaryName(name) || !it->is_regular_file(ec2)) continue;
    Version v;
    v.size = fs::file_size(it->path(), ec2);
    if (ec2) continue;
    v.mtime = fs::last_write_time(it->path(), ec2);
    if (ec2) continue;
    present.insert(name);
    auto d = delivered_.find(name);
    if (d != delivered_.end() && d->second == v) continue;
    auto [s, inserted] = pending_.try_emplace(name, Seen{v, now, false});
    if (!inserted && !(s->second.version == v)) s->second = Seen{v, now, false};
    if (closed.count(name)) s->second.closed = true;
    const double age = std::chrono::duration<double>(now - s->second.since).count();
    if (s->second.closed || age >= stable_seconds_) {
      ready.push_back(name);
      delivered_[name] = v;
      pending_.erase(s);
    }
  }
  for (auto it = pending_.begin(); it != pending_.end();) {
    it = present.count(it->first) ? std::next(it) : pending_.erase(it);
  }
  return ready;
}

}  // namespace rephoto::live
