// Error images written while they are made (compare's memory stays a few bands of rows).
//
// ErrorExrWriter writes a 1-channel float EXR row band by row band: the same bytes as
// io::WriteExr of the whole image (uncompressed scanlines, one line per chunk, channel "Y"), to
// "<path>.tmp-<pid>", renamed to `path` by Commit(); the temporary file is removed if the
// writer is destroyed before. The rows can be read back (ReadRows) until then, which is how
// the jet PNG of the same values is made afterwards without keeping the image in memory.
// Not thread-safe (one writer per file).
#pragma once

#include <cstdint>
#include <filesystem>
#include <vector>

#include "rephoto/core/image.h"
#include "rephoto/metrics/metrics.h"

namespace rephoto::compare {

class ErrorExrWriter {
 public:
  // Creates the temporary file and writes the header and the line offset table. Throws Error
  // naming `path` when the file cannot be created.
  ErrorExrWriter(const std::filesystem::path& path, int width, int height);
  ~ErrorExrWriter();
  ErrorExrWriter(const ErrorExrWriter&) = delete;
  ErrorExrWriter& operator=(const ErrorExrWriter&) = delete;

  // Appends rows [y0, y1) (y0 = the number of rows written so far): (y1 - y0) * width floats.
  void WriteRows(int y0, int y1, const float* values);
  // Reads rows [y0, y1) back (all rows must have been written).
  void ReadRows(int y0, int y1, float* values) const;
  // Closes the file and renames it to its final name.
  void Commit();

 private:
  std::filesystem::path path_, temporary_;
  int width_, height_;
  int fd_ = -1;
  int rows_written_ = 0;
  uint64_t data_offset_ = 0;  // file offset of row 0's chunk
  std::vector<uint8_t> chunks_;
};

// RGBA of `count` error values: JetColor over [low, high] (low > high reverses), alpha 0 and
// black where the value is NaN. The one colour mapping of ColourErrorImage and WriteErrorPng.
void ColourErrorValues(const float* values, size_t count, float low, float high, uint8_t* rgba);

// Colours the rows of `exr` with ColourErrorImage's mapping over [low, high] and writes the
// 8-bit RGBA PNG (the same file ColourErrorImage + io::WritePng8 make). `rgba` is scratch
// (width * height * 4 bytes, reused between calls).
void WriteErrorPng(const ErrorExrWriter& exr, int width, int height, float low, float high,
                   const std::filesystem::path& path, std::vector<uint8_t>* rgba);

// Writes errors[i] (width x height x 1, NaN = not evaluated) of metrics[i], for the metrics in
// `only` (empty = all), as <folder>/<name>.<metric>.exr and its jet .png over ErrorColourRange
// (compare.h): the same bytes ComparePhotoAndRender writes while it compares, each file
// atomically. `name` may contain '/' (the subfolders must exist). `rgba` is scratch reused
// between calls. Throws Error naming the file that cannot be written.
void WriteErrorImages(const std::vector<Image>& errors, const std::vector<metrics::Metric>& metrics,
                      const std::filesystem::path& folder, const std::string& name,
                      std::vector<uint8_t>* rgba, const std::vector<metrics::Metric>& only = {});

}  // namespace rephoto::compare
