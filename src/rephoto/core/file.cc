#include "rephoto/core/file.h"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <sstream>

#include "rephoto/core/error.h"

namespace rephoto {

namespace fs = std::filesystem;

void WriteFileAtomically(const fs::path& path, const std::function<void(const fs::path&)>& write) {
  std::error_code ec;
  if (path.has_parent_path()) {
    fs::create_directories(path.parent_path(), ec);
    REPHOTO_CHECK(!ec, "{}: cannot create folder: {}", path.parent_path().string(), ec.message());
  }
  fs::path temporary = path;
  temporary += ".tmp-" + std::to_string(::getpid());
  try {
    write(temporary);
  } catch (...) {
    fs::remove(temporary, ec);
    throw;
  }
  fs::rename(temporary, path, ec);
  if (ec) {
    fs::remove(temporary, ec);
    ThrowError("{}: cannot write: {}", path.string(), ec.message());
  }
}

void WriteTextFileAtomically(const fs::path& path, std::string_view content) {
  WriteFileAtomically(path, [&](const fs::path& temporary) {
    std::ofstream out(temporary, std::ios::binary);
    REPHOTO_CHECK(out, "{}: cannot open for writing: {}", path.string(), std::strerror(errno));
    out.write(content.data(), static_cast<std::streamsize>(content.size()));
    out.close();
    REPHOTO_CHECK(out, "{}: write failed (disk full?)", path.string());
  });
}

std::string ReadFileToString(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  REPHOTO_CHECK(in, "{}: cannot open: {}", path.string(), std::strerror(errno));
  std::ostringstream content;
  content << in.rdbuf();
  REPHOTO_CHECK(!in.bad(), "{}: read failed", path.string());
  return content.str();
}

void LinkOrCopyFileAtomically(const std::filesystem::path& from, const std::filesystem::path& to) {
  WriteFileAtomically(to, [&](const std::filesystem::path& temporary) {
    std::error_code ec;
    std::filesystem::create_hard_link(from, temporary, ec);
    if (!ec) return;
    std::filesystem::copy_file(from, temporary, std::filesystem::copy_options::overwrite_existing,
                               ec);
    REPHOTO_CHECK(!ec, "{}: cannot link or copy it to {}: {}", from.string(), to.string(),
                  ec.message());
  });
}

}  // namespace rephoto
