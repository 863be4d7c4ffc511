#include "rephoto/service/test_fixture.h"

#include <archive.h>
#include <archive_entry.h>
#include <fmt/format.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>

#include <cmath>
#include <fstream>
#include <memory>
#include <sstream>

#include "rephoto/service/dataset.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/io/image_io.h"

namespace rephoto::service::testing {
namespace fs = std::filesystem;

std::string MakeArchive(const std::vector<TestEntry>& entries, ArchiveFormat format) {
  // Before the writer, which flushes into it when freed.
  std::vector<char> buffer(64 << 20);
  std::unique_ptr<struct archive, int (*)(struct archive*)> writer(archive_write_new(),
                                                                   archive_write_free);
  if (format == ArchiveFormat::kZip) {
    archive_write_set_format_zip(writer.get());
  } else {
    archive_write_set_format_pax_restricted(writer.get());
    if (format == ArchiveFormat::kTarGz) archive_write_add_filter_gzip(writer.get());
  }
  size_t used = 0;
  REPHOTO_CHECK(
      archive_write_open_memory(writer.get(), buffer.data(), buffer.size(), &used) == ARCHIVE_OK,
      "archive_write_open_memory");
  for (const TestEntry& e : entries) {
    std::unique_ptr<struct archive_entry, void (*)(struct archive_entry*)> entry(
        archive_entry_new(), archive_entry_free);
    archive_entry_set_pathname(entry.get(), e.name.c_str());
    archive_entry_set_perm(entry.get(), 0644);
    using Type = TestEntry::Type;
    switch (e.type) {
      case Type::kFile:
        archive_entry_set_filetype(entry.get(), AE_IFREG);
        archive_entry_set_size(entry.get(), static_cast<la_int64_t>(e.data.size()));
        break;
      case Type::kDirectory:
        archive_entry_set_filetype(entry.get(), AE_IFDIR);
        break;
      case Type::kSymlink:
        archive_entry_set_filetype(entry.get(), AE_IFLNK);
        archive_entry_set_symlink(entry.get(), e.link.c_str());
        break;
      case Type::kHardlink:
        archive_entry_set_filetype(entry.get(), AE_IFREG);
        archive_entry_set_hardlink(entry.get(), e.link.c_str());
        break;
      case Type::kCharDevice:
        archive_entry_set_filetype(entry.get(), AE_IFCHR);
        archive_entry_set_rdev(entry.get(), makedev(1, 3));  // /dev/null
        break;
      case Type::kFifo:
        archive_entry_set_filetype(entry.get(), AE_IFIFO);
        break;
    }
    // ARCHIVE_WARN: a name that is not UTF-8 is written as its raw bytes (hostile tests).
    const int rc = archive_write_header(writer.get(), entry.get());
    REPHOTO_CHECK(rc == ARCHIVE_OK || rc == ARCHIVE_WARN, "header {}: {}", e.name,
                  archive_error_string(writer.get()));
    if (e.type == TestEntry::Type::kFile && !e.data.empty()) {
      archive_write_data(writer.get(), e.data.data(), e.data.size());
    }
  }
  archive_write_close(writer.get());
  return std::string(buffer.data(), used);
}

std::string ReadFile(const fs::path& path) { return ReadFileToString(path); }

fs::path MakeTinyScene(const fs::path& folder, int count, int width, int height,
                       std::mt19937_64& rng) {
  fs::create_directories(folder / "images");
  fs::create_directories(folder / "sparse");
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::string cameras = "# Camera list\n", images = "# Image list\n";
  for (int i = 0; i < count; ++i) {
    // Smooth colours: a sum of random sinusoids per channel.
    Image photo(width, height, 3);
    for (int c = 0; c < 3; ++c) {
      const double fx = 0.05 + 0.3 * uniform(rng), fy = 0.05 + 0.3 * uniform(rng);
      const double phase = 6.28 * uniform(rng);
      for (int y = 0; y < height; ++y) {
        for (int x = 0; x < width; ++x) {
          photo.at(x, y, c) = static_cast<float>(0.5 + 0.3 * std::sin(fx * x + fy * y + phase) *
                                                           std::cos(0.5 * fy * x - 0.7 * fx * y));
        }
      }
    }
    const std::string name = fmt::format("{:02d}.png", i);
    io::WritePng(folder / "images" / name, photo);
    cameras += fmt::format("{} PINHOLE {} {} {} {} {} {}\n", i + 1, width, height, width, width,
                           width / 2.0, height / 2.0);
    // Camera on a circle of radius 4 around the origin at angle a, looking at the origin:
    // rotation about y by -a, translation (0, 0, 4).
    const double a = 6.283185307179586 * i / count;
    images += fmt::format("{} {} 0 {} 0 0 0 4 {} {}\n\n", i + 1, std::cos(-a / 2), std::sin(-a / 2),
                          i + 1, name);
  }
  WriteTextFileAtomically(folder / "sparse" / "cameras.txt", cameras);
  WriteTextFileAtomically(folder / "sparse" / "images.txt", images);
  WriteTextFileAtomically(folder / "sparse" / "points3D.txt", "# 3D point list\n");
  return folder / "sparse";
}

void AddTinyDataset(Store& store, const fs::path& scene_folder, const std::string& name,
                    const std::string& ranking, double public_fraction) {
  DatasetOptions options;
  options.name = name;
  options.description = "A tiny synthetic scene for tests";
  options.scene = scene_folder / "sparse";
  options.read_options.image_root = scene_folder / "images";
  options.scheme = "every:3";
  options.metrics = metrics::ParseMetricList("1-ncc,cb+cr,psnr");
  options.window = 5;
  options.ranking = ranking;
  options.public_fraction = public_fraction;
  AddDataset(store, options);
}

std::string RendersFromPhotos(const fs::path& root, const std::string& dataset, double noise,
                              std::mt19937_64& rng, double coverage) {
  std::uniform_real_distribution<double> uniform(-noise, noise);
  std::vector<TestEntry> entries;
  const fs::path folder = SecretPhotoFolder(root, dataset);
  std::vector<fs::path> photos;
  for (const auto& entry : fs::directory_iterator(folder)) photos.push_back(entry.path());
  std::sort(photos.begin(), photos.end());
  const fs::path work = root / ".." / "renders-tmp";
  fs::create_directories(work);
  for (const fs::path& path : photos) {
    const Image photo = io::ReadImage(path);
    Image render(photo.width(), photo.height(), 4, 1.0f);
    const double side = std::sqrt(std::clamp(coverage, 0.0, 1.0));
    const int block_width = static_cast<int>(std::lround(side * photo.width()));
    const int block_height = static_cast<int>(std::lround(side * photo.height()));
    for (int y = 0; y < photo.height(); ++y) {
      for (int x = 0; x < photo.width(); ++x) {
        if (x >= block_width || y >= block_height) {
          for (int c = 0; c < 4; ++c) render.at(x, y, c) = 0.0f;
          continue;
        }
        for (int c = 0; c < 3; ++c) {
          render.at(x, y, c) =
              std::clamp(static_cast<float>(photo.at(x, y, c) + uniform(rng)), 0.0f, 1.0f);
        }
      }
    }
    const fs::path png = work / (path.stem().string() + ".png");
    io::WritePng(png, render);
    entries.push_back({png.filename().string(), ReadFileToString(png)});
  }
  fs::remove_all(work);
  return MakeArchive(entries, ArchiveFormat::kTar);
}

}  // namespace rephoto::service::testing
