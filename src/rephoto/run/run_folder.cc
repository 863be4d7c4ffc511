#include "rephoto/run/run_folder.h"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <system_error>
#include <utility>

#include "rephoto/core/error.h"

namespace rephoto::run {
namespace fs = std::filesystem;

namespace {

std::string MarkLine(std::string_view kind) { return fmt::format("rephoto {} run folder", kind); }

// The first two lines of the mark file (kind line, "pid N"); empty when unreadable.
std::pair<std::string, std::string> ReadMark(const fs::path& path) {
  std::ifstream in(path);
  std::string kind_line, pid_line;
  std::getline(in, kind_line);
  std::getline(in, pid_line);
  return {kind_line, pid_line};
}

}  // namespace

RunFolder::RunFolder(RunFolder&& other) noexcept
    : dir_(std::move(other.dir_)), fd_(std::exchange(other.fd_, -1)) {}

RunFolder& RunFolder::operator=(RunFolder&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    dir_ = std::move(other.dir_);
    fd_ = std::exchange(other.fd_, -1);
  }
  return *this;
}

RunFolder::~RunFolder() {
  if (fd_ >= 0) ::close(fd_);  // closing the last descriptor releases the flock
}

bool IsEmptyFolder(const fs::path& dir) {
  std::error_code ec;
  fs::directory_iterator it(dir, ec);
  return ec || it == fs::directory_iterator();
}

RunFolder OpenRunFolder(const fs::path& dir, std::string_view kind,
                        const std::function<bool(const fs::path&)>& legacy_owner) {
  std::error_code ec;
  const fs::file_status status = fs::symlink_status(dir, ec);
  if (fs::exists(status)) {
    REPHOTO_CHECK(fs::is_directory(fs::status(dir, ec)), "{}: exists and is not a folder",
                  dir.string());
  } else {
    fs::create_directories(dir, ec);
    REPHOTO_CHECK(!ec, "{}: cannot create the folder: {}", dir.string(), ec.message());
  }
  const fs::path mark = dir / kRunMarkFile;
  const std::string mark_line = MarkLine(kind);
  if (fs::exists(fs::symlink_status(mark, ec))) {
    REPHOTO_CHECK(fs::is_regular_file(fs::symlink_status(mark, ec)),
                  "{}: is not a regular file; this is not a rephoto run folder", mark.string());
    const std::string kind_line = ReadMark(mark).first;
    REPHOTO_CHECK(kind_line == mark_line,
                  "{}: holds another kind of run ('{}'), not a rephoto {} run; use another --out",
                  dir.string(), kind_line.substr(0, 80), kind);
  } else if (!IsEmptyFolder(dir) && !(legacy_owner && legacy_owner(dir))) {
    ThrowError("{}: the folder is not empty and holds no rephoto {} run; use an empty or new --out",
               dir.string(), kind);
  }

  RunFolder folder;
  folder.dir_ = dir;
  folder.fd_ = ::open(mark.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
  REPHOTO_CHECK(folder.fd_ >= 0, "{}: cannot open: {}", mark.string(), std::strerror(errno));
  if (::flock(folder.fd_, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    REPHOTO_CHECK(error == EWOULDBLOCK, "{}: cannot lock: {}", mark.string(), std::strerror(error));
    const std::string pid_line = ReadMark(mark).second;
    ThrowError(
        "{}: another rephoto {}{} is writing this run folder; wait for it or use another "
        "--out",
        dir.string(), kind,
        pid_line.size() > 4 && pid_line.compare(0, 4, "pid ") == 0 ? " (" + pid_line + ")"
                                                                   : std::string());
  }
  const std::string content = fmt::format("{}\npid {}\n", mark_line, ::getpid());
  bool written = ::ftruncate(folder.fd_, 0) == 0;
  written = written && ::pwrite(folder.fd_, content.data(), content.size(), 0) ==
                           static_cast<ssize_t>(content.size());
  REPHOTO_CHECK(written, "{}: cannot write: {}", mark.string(), std::strerror(errno));
  return folder;
}

}  // namespace rephoto::run
