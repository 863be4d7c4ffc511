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
// Memory: each call decodes its file at full size (JPEG photos at a reduced size) into the
// caller's ThumbnailScratch when one is given, so that a series of thumbnails reuses the same
// buffers instead of touching fresh memory for every image (a 12 MP error image's buffers are
// about 150 MB: page faults were half of a report's CPU); ThumbnailScratches lends them to the
// tasks of a parallel loop. The price is memory: a scratch keeps its largest buffers until the
// loop ends (per image processed at once, the largest decoded file plus an error image's
// (value, weight) pairs: about 250 MB at 12 MP). Measured on 6 examples of 12 MP (JPEG
// photos, PNG renderings, EXR errors, 2 threads): 1.62 s wall / 853 MiB peak against 2.47 s /
// 627 MiB with fresh buffers and full-size JPEG decoding.
//
// Cache: the thumbnails made are kept for the process (core/recent_cache.h: at most 64 MiB of
// data URIs in 4096 entries, the least recently used dropped first), keyed by what they were
// made of: the kind, the width, the metric, and for each file its absolute path, inode, size and
// modification and status-change times. The runs of one scene share their photos, so the
// reports of several runs in one process (`rephoto demo`'s six) and a comparison report of
// several runs encode each photo once per width. A file rewritten (a new inode, size or time) is
// made again; a failure is not kept; a thumbnail whose file changed while it was made is not
// kept either.
//
// Thread safety: reentrant (reads the images named; the cache is the only shared state and
// locks itself) as long as each thread uses its own scratch.
#pragma once

#include <tbb/task_arena.h>

#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "rephoto/core/image.h"
#include "rephoto/core/parallel.h"
#include "rephoto/metrics/metrics.h"

namespace rephoto::report {

struct Thumbnail {
  std::string data_uri;  // empty on failure
  std::string error;     // why there is no image
  int width = 0;
  int height = 0;
};

// The photo at most `width` wide (never enlarged). JPEG photos are decoded at a reduced size
// (io::ReadImagePreview: DCT scaling), so a 12 MP photo costs a fraction of a full decode; the
// thumbnail is then close to, not equal to, a resampled full decode (it is only shown).
// Buffers reused from one thumbnail to the next (see "Memory" above); null = fresh ones.
struct ThumbnailScratch {
  Image decoded;   // the file at full size (a JPEG photo at reduced size)
  Image weighted;  // an error image's (value, weight) pairs, or a rendering's coverage
  Image shrunk;    // the thumbnail-size result
};

// A pool of ThumbnailScratch for a ParallelFor over images: With() lends one to the calling
// task and takes it back afterwards, so there are about as many as threads working at once
// (no thread indices: works from any thread, also outside TBB's workers). The buffers are
// freed with this object. Thread-safe.
class ThumbnailScratches {
 public:
  // Runs fn(scratch) with a scratch no other task holds, isolated (tbb::this_task_arena::
  // isolate): while a nested parallel loop inside fn waits, this thread does not start another
  // image (which would need another scratch).
  template <typename Fn>
  void With(Fn&& fn) {
    std::unique_ptr<ThumbnailScratch> scratch = Acquire();
    try {
      tbb::this_task_arena::isolate([&] { fn(scratch.get()); });
    } catch (...) {
      Release(std::move(scratch));
      throw;
    }
    Release(std::move(scratch));
  }

 private:
  std::unique_ptr<ThumbnailScratch> Acquire();
  void Release(std::unique_ptr<ThumbnailScratch> scratch);
  std::mutex mutex_;
  std::vector<std::unique_ptr<ThumbnailScratch>> free_;
};

// fn(i, scratch) for every i in [0, count), one image per parallel task (core/parallel.h), each
// call with a scratch of a ThumbnailScratches that no other running call holds.
template <typename Fn>
void ForEachThumbnailJob(int64_t count, Fn&& fn) {
  ThumbnailScratches scratches;
  ParallelFor(0, count, 1, [&](int64_t begin, int64_t end) {
    for (int64_t i = begin; i < end; ++i) {
      scratches.With([&](ThumbnailScratch* scratch) { fn(i, scratch); });
    }
  });
}

Thumbnail PhotoThumbnail(const std::filesystem::path& photo, int width,
                         ThumbnailScratch* scratch = nullptr);

// The rephoto and its mask (the rephoto's alpha, or for images without alpha the pixels that
// are not pure black, as compare/compare.h decides coverage).
void RenderThumbnails(const std::filesystem::path& render, int width, Thumbnail* rephoto,
                      Thumbnail* mask, ThumbnailScratch* scratch = nullptr);

// From errors/<name>.<metric>.exr when present (exact values), else the jet PNG written next
// to it (shrunk as colours).
Thumbnail ErrorThumbnail(const std::filesystem::path& exr, const std::filesystem::path& png,
                         metrics::Metric metric, int width, ThumbnailScratch* scratch = nullptr);

}  // namespace rephoto::report
