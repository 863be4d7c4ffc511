// Downscaled images embedded in reports as data URIs.
//
// A thumbnail is at most `width` pixels wide (never enlarged), the aspect ratio kept, shrunk
// with compare::ResizeImage (area filter). Photos and rephotos become JPEG (quality 85; a
// rephoto is composited over black where its alpha is below 1, black being "not covered" in
// the renderers' convention), masks 1-channel PNG (white = covered), error images JPEG (4:4:4,
// quality 80): values are shrunk NaN-aware (a thumbnail pixel is the mean of the evaluated
// values under it, and not evaluated when fewer than half of them were), jet-coloured over the
// metric's fixed range (compare::ErrorColourRange), and shown over a grey checkerboard where
// not evaluated.
// Failures never throw: a missing or unreadable file gives an empty data_uri and the reason in
// `error` (the report shows it in place of the image).
//
// Thread safety: reentrant (reads the images named; no shared state).
#pragma once

#include <filesystem>
#include <string>

#include "rephoto/metrics/metrics.h"

namespace rephoto::report {

struct Thumbnail {
  std::string data_uri;  // empty on failure
  std::string error;     // why there is no image
  int width = 0;
  int height = 0;
};

Thumbnail PhotoThumbnail(const std::filesystem::path& photo, int width);

// The rephoto and its mask (the rephoto's alpha, or for images without alpha the pixels that
// are not pure black, as compare/compare.h decides coverage).
void RenderThumbnails(const std::filesystem::path& render, int width, Thumbnail* rephoto,
                      Thumbnail* mask);

// From errors/<name>.<metric>.exr when present (exact values), else the jet PNG written next
// to it (shrunk as colours).
Thumbnail ErrorThumbnail(const std::filesystem::path& exr, const std::filesystem::path& png,
                         metrics::Metric metric, int width);

}  // namespace rephoto::report
