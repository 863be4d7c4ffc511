#include "rephoto/service/archive.h"

#include <archive.h>
#include <archive_entry.h>
#include <fcntl.h>
#include <fmt/format.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <fstream>
#include <memory>

#include "rephoto/service/text.h"
#include "rephoto/core/file.h"
#include "rephoto/scene/image_name.h"

namespace rephoto::service {
namespace {

using ArchivePtr = std::unique_ptr<struct archive, int (*)(struct archive*)>;

[[noreturn]] void Refuse(int status, const std::string& message) { throw Refused(status, message); }

// libarchive's reason, which may be null (found by fuzz_service_upload).
std::string ReaderError(struct archive* reader) {
  const char* text = archive_error_string(reader);
  return text ? Printable(text) : "unknown error";
}

std::string Lower(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

bool IsRenderExtension(const std::string& extension) {
  return extension == ".png" || extension == ".jpg" || extension == ".jpeg" || extension == ".exr";
}

// Closes a file descriptor on scope exit.
struct FileDescriptor {
  explicit FileDescriptor(int fd) : fd(fd) {}
  ~FileDescriptor() {
    if (fd >= 0) close(fd);
  }
  int fd;
};

// Copies the current entry's data into `fd`, adding to *total and refusing past the limit.
void CopyEntryData(struct archive* reader, int fd, const std::string& name,
                   const ArchiveLimits& limits, int64_t* total) {
  const void* block = nullptr;
  size_t size = 0;
  la_int64_t offset = 0;
  for (;;) {
    const int rc = archive_read_data_block(reader, &block, &size, &offset);
    if (rc == ARCHIVE_EOF) return;
    if (rc != ARCHIVE_OK) {
      Refuse(400, fmt::format("archive entry '{}': {}", name, ReaderError(reader)));
    }
    *total += static_cast<int64_t>(size);
    if (*total > limits.max_bytes) {
      Refuse(413, fmt::format("archive entry '{}': the renders exceed {} bytes when extracted",
                              name, limits.max_bytes));
    }
    // Sparse entries give offsets; write where they say (pwrite never leaves the file).
    const auto* bytes = static_cast<const char*>(block);
    while (size > 0) {
      const ssize_t written = pwrite(fd, bytes, size, offset);
      REPHOTO_CHECK(written > 0, "cannot write the render '{}'", name);
      bytes += written;
      size -= static_cast<size_t>(written);
      offset += written;
    }
  }
}

// The checked stem and lower-case extension of a regular-file entry, or a refusal.
std::pair<std::string, std::string> CheckEntryName(const std::string& raw,
                                                   const std::set<std::string>& stems) {
  std::string name;
  try {
    name = scene::CheckedImageName(raw, "archive");
  } catch (const Error& error) {
    Refuse(400, error.what());
  }
  const std::filesystem::path path(name);
  const std::string extension = Lower(path.extension().string());
  const std::string stem = path.stem().string();
  if (!IsRenderExtension(extension)) {
    Refuse(400, fmt::format("archive entry '{}': not a .png, .jpg, .jpeg or .exr file", name));
  }
  if (!stems.count(stem)) {
    Refuse(400,
           fmt::format("archive entry '{}': '{}' is not a test image of this dataset", name, stem));
  }
  return {stem, extension};
}

ArchivePtr NewReader() {
  ArchivePtr reader(archive_read_new(), archive_read_free);
  REPHOTO_CHECK(reader, "libarchive: out of memory");
  archive_read_support_format_tar(reader.get());
  archive_read_support_format_zip(reader.get());
  archive_read_support_filter_gzip(reader.get());
  return reader;
}

// Extraction from an opened reader (see ExtractRenders).
std::vector<ExtractedFile> ExtractFromReader(struct archive* reader,
                                             const std::set<std::string>& stems,
                                             const ArchiveLimits& limits,
                                             const std::filesystem::path& out_dir) {
  std::vector<ExtractedFile> files;
  std::set<std::string> seen;
  int64_t total = 0;
  size_t entries = 0;
  for (;;) {
    struct archive_entry* entry = nullptr;
    const int rc = archive_read_next_header(reader, &entry);
    if (rc == ARCHIVE_EOF) break;
    if (rc != ARCHIVE_OK && rc != ARCHIVE_WARN) {
      Refuse(400, fmt::format("malformed archive after {} entries: {}", files.size(),
                              ReaderError(reader)));
    }
    const char* raw_name = archive_entry_pathname(entry);
    // Names appear in messages only in printable form (the raw bytes may be anything).
    const std::string raw = Printable(raw_name ? raw_name : "");
    if (++entries > limits.max_files) {
      Refuse(413, fmt::format("archive entry '{}': more than {} entries", raw, limits.max_files));
    }
    const mode_t type = archive_entry_filetype(entry);
    if (type == AE_IFDIR) continue;
    if (type != AE_IFREG || archive_entry_hardlink(entry) != nullptr) {
      Refuse(400, fmt::format("archive entry '{}': not a regular file (links, devices and "
                              "FIFOs are refused)",
                              raw));
    }
    if (!raw_name || !IsCleanText(raw_name)) {
      Refuse(400, fmt::format("archive entry '{}': the name is not UTF-8 text without control "
                              "characters",
                              raw));
    }
    const auto [stem, extension] = CheckEntryName(raw_name, stems);
    if (!seen.insert(stem).second) {
      Refuse(400, fmt::format("archive entry '{}': a second render of '{}'", raw, stem));
    }
    const std::filesystem::path path = out_dir / (stem + extension);
    FileDescriptor fd(
        open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0644));
    REPHOTO_CHECK(fd.fd >= 0, "{}: cannot create the render", path.string());
    CopyEntryData(reader, fd.fd, raw, limits, &total);
    files.push_back({stem, path, 0});
    struct stat info {};
    if (fstat(fd.fd, &info) == 0) files.back().size = info.st_size;
  }
  std::sort(files.begin(), files.end(),
            [](const ExtractedFile& a, const ExtractedFile& b) { return a.stem < b.stem; });
  return files;
}

}  // namespace

std::vector<ExtractedFile> ExtractRenders(std::string_view archive,
                                          const std::set<std::string>& stems,
                                          const ArchiveLimits& limits,
                                          const std::filesystem::path& out_dir) {
  ArchivePtr reader = NewReader();
  if (archive.empty() ||
      archive_read_open_memory(reader.get(), archive.data(), archive.size()) != ARCHIVE_OK) {
    Refuse(400, fmt::format("not a tar or zip archive: {}", archive.empty()
                                                                ? std::string("the body is empty")
                                                                : ReaderError(reader.get())));
  }
  return ExtractFromReader(reader.get(), stems, limits, out_dir);
}

std::vector<ExtractedFile> ExtractRendersFromFile(const std::filesystem::path& archive,
                                                  const std::set<std::string>& stems,
                                                  const ArchiveLimits& limits,
                                                  const std::filesystem::path& out_dir) {
  std::error_code error;
  const auto size = std::filesystem::file_size(archive, error);
  if (error || size == 0) Refuse(400, "not a tar or zip archive: the body is empty");
  ArchivePtr reader = NewReader();
  if (archive_read_open_filename(reader.get(), archive.c_str(), 1 << 16) != ARCHIVE_OK) {
    Refuse(400, fmt::format("not a tar or zip archive: {}", ReaderError(reader.get())));
  }
  return ExtractFromReader(reader.get(), stems, limits, out_dir);
}

void WriteTar(const std::filesystem::path& path, const std::vector<TarMember>& members) {
  WriteFileAtomically(path, [&](const std::filesystem::path& temporary) {
    ArchivePtr writer(archive_write_new(), archive_write_free);
    REPHOTO_CHECK(writer, "libarchive: out of memory");
    archive_write_set_format_pax_restricted(writer.get());
    REPHOTO_CHECK(archive_write_open_filename(writer.get(), temporary.c_str()) == ARCHIVE_OK,
                  "{}: {}", temporary.string(), archive_error_string(writer.get()));
    std::vector<char> buffer(1 << 16);
    for (const TarMember& member : members) {
      std::ifstream in(member.source, std::ios::binary);
      REPHOTO_CHECK(in, "{}: cannot read", member.source.string());
      std::unique_ptr<struct archive_entry, void (*)(struct archive_entry*)> entry(
          archive_entry_new(), archive_entry_free);
      archive_entry_set_pathname(entry.get(), member.name.c_str());
      archive_entry_set_size(entry.get(),
                             static_cast<la_int64_t>(std::filesystem::file_size(member.source)));
      archive_entry_set_filetype(entry.get(), AE_IFREG);
      archive_entry_set_perm(entry.get(), 0644);
      REPHOTO_CHECK(archive_write_header(writer.get(), entry.get()) == ARCHIVE_OK, "{}: {}",
                    path.string(), archive_error_string(writer.get()));
      while (in) {
        in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
        const auto count = in.gcount();
        if (count <= 0) break;
        REPHOTO_CHECK(
            archive_write_data(writer.get(), buffer.data(), static_cast<size_t>(count)) == count,
            "{}: {}", path.string(), archive_error_string(writer.get()));
      }
    }
    REPHOTO_CHECK(archive_write_close(writer.get()) == ARCHIVE_OK, "{}: {}", path.string(),
                  archive_error_string(writer.get()));
  });
}

}  // namespace rephoto::service
