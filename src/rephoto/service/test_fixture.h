// Test helpers of the benchmark tests: archives built in memory with libarchive's writer
// (including the hostile kinds an attacker would send) and a tiny calibrated scene on disk.
//
// Thread safety: test helpers; call them from the test's thread.
#pragma once

#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "rephoto/service/store.h"

namespace rephoto::service::testing {

struct TestEntry {
  enum class Type { kFile, kDirectory, kSymlink, kHardlink, kCharDevice, kFifo };
  std::string name;
  std::string data;  // kFile: the content
  Type type = Type::kFile;
  std::string link;  // kSymlink / kHardlink: the target
};

enum class ArchiveFormat { kTar, kTarGz, kZip };

// The archive's bytes.
std::string MakeArchive(const std::vector<TestEntry>& entries, ArchiveFormat format);

std::string ReadFile(const std::filesystem::path& path);

// A COLMAP text scene in `folder` (sparse/ and images/): `count` PNG photos "NN.png" of
// width x height with smooth random colours in [0.2, 0.8] (never ill-exposed), PINHOLE cameras
// on a circle looking at the origin. Returns the sparse folder.
std::filesystem::path MakeTinyScene(const std::filesystem::path& folder, int count, int width,
                                    int height, std::mt19937_64& rng);

// Adds the tiny scene as dataset `name` (scheme every:3, metrics 1-ncc,cb+cr,psnr, window 5)
// with the ranking rule and public fraction given.
void AddTinyDataset(Store& store, const std::filesystem::path& scene_folder,
                    const std::string& name, const std::string& ranking = "filled",
                    double public_fraction = 1);

// A tar of the dataset's secret photos re-encoded as RGBA PNG (alpha 1), each with `noise`
// (uniform in [-noise, noise], clamped to [0, 1]) added: a perfect submission for noise 0.
// With `coverage` < 1 only the top-left block of about that fraction of the pixels is rendered
// (alpha 1); the rest has alpha 0 (not rendered).
std::string RendersFromPhotos(const std::filesystem::path& root, const std::string& dataset,
                              double noise, std::mt19937_64& rng, double coverage = 1);

}  // namespace rephoto::service::testing
