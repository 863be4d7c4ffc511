#include "rephoto/eval/rephoto_views.h"

#include <tbb/global_control.h>

#include <future>
#include <memory>
#include <mutex>

#include "rephoto/compare/error_images.h"
#include "rephoto/compare/resample.h"
#include "rephoto/core/background_worker.h"
#include "rephoto/core/file.h"
#include "rephoto/core/limits.h"
#include "rephoto/core/process.h"
#include "rephoto/eval/command_template.h"
#include "rephoto/eval/compat_numbers.h"
#include "rephoto/eval/keys.h"
#include "rephoto/eval/run_records.h"
#include "rephoto/io/image_io.h"

namespace rephoto::eval {
namespace fs = std::filesystem;

namespace {

void Advance(Progress* progress, const std::string& item) {
  if (progress != nullptr) progress->Advance(item);
}

void RemoveStaleErrorImages(const fs::path& errors_dir, const std::string& stem) {
  std::error_code ec;
  for (metrics::Metric metric : metrics::AllMetrics()) {
    const std::string base = stem + "." + std::string(metrics::MetricName(metric));
    fs::remove(errors_dir / (base + ".exr"), ec);
    fs::remove(errors_dir / (base + ".png"), ec);
  }
}

// The photo at the evaluation resolution: the original, or its downscaled copy, cached once as
// 16-bit PNG (keeps the filtered values to 1/65535) and compared as read back.
void EvalPhoto(const RunContext& s, Tally& tally, PreparedView& view, const TestView& test,
               fs::path* used_path) {
  Image* scratch = &view.eval_photo;
  view.photo_is_8bit = false;
  const camera::Camera& full = s.scene.CameraOf(s.scene.views[test.view_index]);
  if (full.width == test.camera.width && full.height == test.camera.height) {
    if (s.options.compat) {
      io::ReadImage(test.photo, scratch);
    } else {
      view.photo_is_8bit = io::ReadImage8(test.photo, &view.photo8, scratch);
    }
    *used_path = test.photo;
    return;
  }
  const fs::path cache_dir = s.CacheDir() / "eval_photos";
  const fs::path cached = fs::absolute(cache_dir / (test.stem + ".png")).lexically_normal();
  const fs::path key_file = cache_dir / (test.stem + ".key");
  const std::string key =
      Hasher().Add(test.photo_hash).AddInt(test.camera.width).AddInt(test.camera.height).Hex();
  std::error_code ec;
  if (fs::is_regular_file(cached, ec) && fs::is_regular_file(key_file, ec)) {
    try {
      if (ReadFileToString(key_file) == key) {
        io::ReadImage(cached, scratch);
        if (scratch->width() == test.camera.width && scratch->height() == test.camera.height) {
          *used_path = cached;
          return;
        }
      }
    } catch (const Error&) {
      // recompute below
    }
  }
  Image& photo = view.full_photo;
  io::ReadImage(test.photo, &photo);
  REPHOTO_CHECK(photo.width() == full.width && photo.height() == full.height,
                "{}: photo is {}x{} but its camera is {}x{}", test.photo.string(), photo.width(),
                photo.height(), full.width, full.height);
  compare::ResizeImage(photo, test.camera.width, test.camera.height, scratch);
  io::WritePngAndQuantize(cached, scratch, io::PngDepth::k16, io::PngCompression::kNone);
  WriteTextFileAtomically(key_file, key);
  tally.Count(&EvaluateCounters::photos_downscaled);
  *used_path = cached;
}

std::optional<Mask> EvalMask(const TestView& test) {
  if (test.mask.empty()) return std::nullopt;
  Mask mask = io::ReadMask(test.mask);
  if (mask.width() != test.camera.width || mask.height() != test.camera.height) {
    Mask scaled;
    compare::ResizeMask(mask, test.camera.width, test.camera.height, &scaled);
    return scaled;
  }
  return mask;
}

compare::CompareOptions CompareSettings(const EvaluateOptions& o) {
  compare::CompareOptions c;
  c.metrics = o.metrics;
  c.metric_options = o.metric_options;
  c.exposure = o.exposure;
  c.lpips_weights = o.lpips_weights;
  c.lpips_net = o.lpips_net;
  c.resize = o.resize;
  c.write_error_images = o.error_images;
  c.error_image_metrics = ErrorImageMetrics(o);
  return c;
}

// The rendering of the view into view.render: reused from disk, rendered, or the external one.
// 8-bit files are read as bytes (view.render8) unless `floats` (--compat).
fs::path ObtainRendering(Tally& tally, PreparedView& view, const FoldPlan& fold,
                         const TestView& test, render::ViewRenderer* renderer,
                         const ViewOutcome& outcome, bool write_depth, bool floats) {
  const fs::path renders_dir = fold.dir / "renders";
  const auto read = [&](const fs::path& path) {
    if (floats) {
      io::ReadImage(path, &view.render);
      view.render_is_8bit = false;
    } else {
      view.render_is_8bit = io::ReadImage8(path, &view.render8, &view.render);
    }
  };
  if (outcome.reuse_render) {
    // Only compare settings changed: the rendering on disk is the one this view needs.
    read(renders_dir / (test.stem + ".png"));
    return renders_dir / (test.stem + ".png");
  }
  if (renderer != nullptr) {
    renderer->Render(test.camera, test.pose, &view.rephoto);
    // Compared as the PNG written.
    if (floats) {
      render::WriteRephoto(renders_dir, test.stem, &view.rephoto, write_depth);
      std::swap(view.render, view.rephoto.color);  // the next view renders into the previous one
      view.render_is_8bit = false;
    } else {
      render::WriteRephoto(renders_dir, test.stem, view.rephoto, write_depth, &view.render8);
      view.render_is_8bit = true;
    }
    tally.Count(&EvaluateCounters::views_rendered);
    return renders_dir / (test.stem + ".png");
  }
  const fs::path path = FindImageByStem(fold.out_dir, test.stem);
  REPHOTO_CHECK(!path.empty(), "{}: no rendering named '{}'", fold.out_dir.string(), test.stem);
  read(path);
  return path;
}

// The preparer's step (any thread): the rendering, the photo at the evaluation resolution and
// the masks of view `test` into `view`. An Error is kept in view.failure; others propagate.
void PrepareView(const RunContext& s, Tally& tally, PreparedView& view, const FoldPlan& fold,
                 bool gaussians, const TestView& test, render::ViewRenderer* renderer,
                 ViewOutcome& outcome) {
  view.failure.clear();
  try {
    auto start = Clock::now();
    view.render_path =
        ObtainRendering(tally, view, fold, test, renderer, outcome,
                        WritesDepthImages(s.options, gaussians), s.options.compat.has_value());
    outcome.render_seconds = Seconds(start);
    tally.AddSeconds(&EvaluateTimings::render, outcome.render_seconds);
    start = Clock::now();
    EvalPhoto(s, tally, view, test, &view.photo_path);
    view.mask = EvalMask(test);
    // Gaussians: a pixel is the model's where its alpha reaches --min-alpha (the PNG's alpha,
    // so a reused rendering gives the same coverage).
    view.min_alpha =
        gaussians && (renderer != nullptr || outcome.reuse_render) ? s.options.min_alpha : 0;
    outcome.compare_seconds = Seconds(start);
    tally.AddSeconds(&EvaluateTimings::photos, outcome.compare_seconds);
  } catch (const UsageError&) {
    throw;
  } catch (const Error& e) {
    view.failure = e.what();
  }
}

// The caller's step: compares the prepared view. Error images go to `error_images` when given
// (the writer writes them), else they are written while compared.
void CompareView(const RunContext& s, Tally& tally, ViewWorkspace& ws, const PreparedView& view,
                 const FoldPlan& fold, const TestView& test, std::vector<Image>* error_images,
                 ViewOutcome& outcome) {
  const auto start = Clock::now();
  const fs::path errors_dir = fold.dir / "errors";
  if (s.options.error_images && error_images == nullptr) {
    RemoveStaleErrorImages(errors_dir, test.stem);
    std::error_code ec;
    fs::create_directories((errors_dir / test.stem).parent_path(), ec);
  }
  compare::CompareOptions settings = CompareSettings(s.options);
  settings.min_alpha = view.min_alpha;
  const auto compare = [&](const auto& photo, const auto& render) {
    return compare::ComparePhotoAndRender(
        settings, test.stem, view.photo_path, fs::path(s.Relative(view.render_path)), photo, render,
        view.mask ? &*view.mask : nullptr, nullptr, errors_dir, &ws.compare, error_images);
  };
  if (view.photo_is_8bit) {
    outcome.image = view.render_is_8bit ? compare(view.photo8, view.render8)
                                        : compare(view.photo8, view.render);
  } else {
    outcome.image = view.render_is_8bit ? compare(view.eval_photo, view.render8)
                                        : compare(view.eval_photo, view.render);
  }
  if (s.options.compat) {  // the numbers papers publish, from the same rendering and photo
    outcome.compat = CompareViewCompat(s.options, test.stem, view.photo_path,
                                       fs::path(s.Relative(view.render_path)), view.eval_photo,
                                       view.render, &ws.compare);
  }
  const double seconds = Seconds(start);
  outcome.compare_seconds += seconds;
  tally.AddSeconds(&EvaluateTimings::compare, seconds);
  tally.Count(&EvaluateCounters::views_compared);
}

// The writer's step: the error images handed over (if any), then the view record, last.
void WriteView(const RunContext& s, Tally& tally, ViewWorkspace& ws, const FoldPlan& fold,
               const TestView& test, const std::vector<Image>* error_images, ViewOutcome& outcome) {
  const auto start = Clock::now();
  if (error_images != nullptr) {
    const fs::path errors_dir = fold.dir / "errors";
    RemoveStaleErrorImages(errors_dir, test.stem);
    std::error_code ec;
    fs::create_directories((errors_dir / test.stem).parent_path(), ec);
    compare::WriteErrorImages(*error_images, s.options.metrics, errors_dir, test.stem, &ws.rgba,
                              ErrorImageMetrics(s.options));
  }
  outcome.ok = true;
  WriteViewRecord(s, fold, outcome);
  tally.AddSeconds(&EvaluateTimings::write, Seconds(start));
}

void FailView(const FoldPlan& fold, const TestView& test, const std::string& why,
              ViewOutcome& outcome) {
  outcome.ok = false;
  outcome.message = fmt::format("{} {}: {}", fold.name, test.stem, why);
  LogWarning(outcome.message);
}

// The largest view of `todo` in pixels.
uint64_t LargestView(const FoldPlan& fold, const std::vector<size_t>& todo) {
  uint64_t pixels = 0;
  for (size_t i : todo) {
    const camera::Camera& camera = fold.tests[i].camera;
    pixels = std::max<uint64_t>(pixels, static_cast<uint64_t>(camera.width) * camera.height);
  }
  return pixels;
}

// Bytes per pixel of one more view in flight: the renderer's buffers, the rendering, the
// photo at full and evaluation size, masks (about 64).
constexpr uint64_t kPreparedViewBytesPerPixel = 64;

}  // namespace

std::vector<size_t> PlanViews(const RunContext& s, const FoldPlan& fold, const FoldModel& model,
                              std::vector<ViewOutcome>& views, Tally& tally, Progress* progress,
                              size_t first, size_t count) {
  const bool external = s.source == ModelSource::kRender;
  const std::string compare_key = CompareSettingsKey(s.options);
  views.resize(fold.tests.size());
  const size_t end = count == 0 ? fold.tests.size() : std::min(fold.tests.size(), first + count);
  std::vector<size_t> todo;
  for (size_t i = first; i < end; ++i) {
    const TestView& test = fold.tests[i];
    ViewOutcome& outcome = views[i];
    outcome.stem = test.stem;
    outcome.name = test.name;
    outcome.record = fold.dir / "views" / (test.stem + ".json");
    std::string render_hash;
    if (external) {
      const fs::path image = FindImageByStem(fold.out_dir, test.stem);
      render_hash = image.empty() ? std::string() : s.hashes->Hash(image);
    }
    outcome.key = ViewKey(test, model.base_key, render_hash, compare_key);
    const std::optional<Json> previous = run::ReadJsonRecord(outcome.record);  // read once
    if (!external) {
      outcome.render_key = RenderKey(model.base_key, test);
      std::error_code ec;
      outcome.reuse_render =
          previous && previous->value("render_key", "") == outcome.render_key &&
          fs::is_regular_file(fold.dir / "renders" / (test.stem + ".png"), ec) &&
          (!WritesDepthImages(s.options, model.gaussians) ||
           fs::is_regular_file(fold.dir / "renders" / (test.stem + ".depth.exr"), ec));
    }
    if (ReadViewRecord(s, outcome.record, previous, outcome.key, &outcome)) {
      outcome.ok = true;
      outcome.reused = true;
      outcome.image.name = test.stem;
      tally.Count(&EvaluateCounters::views_reused);
      Advance(progress, fmt::format("{} {} (done before)", fold.name, test.stem));
    } else {
      todo.push_back(i);
    }
  }
  return todo;
}

void EvaluateViews(const RunContext& s, ViewWorkspace& ws, const FoldPlan& fold,
                   const FoldModel& model, const std::vector<size_t>& todo,
                   render::ViewRenderer* renderer, std::vector<ViewOutcome>& views, Tally& tally,
                   Progress* progress) {
  if (todo.empty()) return;
  const auto start = Clock::now();
  // The pipeline holds a second view, and two views' error images, when each fits in a quarter
  // of --max-memory; else views go one at a time and error images are streamed.
  const uint64_t pixels = LargestView(fold, todo);
  const bool pipelined =
      todo.size() > 1 &&
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism) > 1 &&
      kPreparedViewBytesPerPixel * pixels <= MaxMemoryBytes() / 4;
  const bool errors_later =
      pipelined && s.options.error_images &&
      2 * s.options.metrics.size() * pixels * sizeof(float) <= MaxMemoryBytes() / 4;
  const auto prepare = [&](size_t k) {
    PrepareView(s, tally, ws.views[k % 2], fold, model.gaussians, fold.tests[todo[k]], renderer,
                views[todo[k]]);
  };
  const auto write = [&](size_t k) {
    const TestView& test = fold.tests[todo[k]];
    ViewOutcome& outcome = views[todo[k]];
    try {
      WriteView(s, tally, ws, fold, test, errors_later ? &ws.error_images[k % 2] : nullptr,
                outcome);
    } catch (const Error& e) {
      FailView(fold, test, e.what(), outcome);
    }
  };
  // Declared after everything their jobs use: on an exception they finish those jobs first.
  std::unique_ptr<BackgroundWorker> preparer, writer;
  std::future<void> prepared, written;
  size_t written_index = 0;
  const auto finish_write = [&] {  // waits for the write of view written_index, shows it done
    if (!written.valid()) return;
    written.get();
    const ViewOutcome& outcome = views[todo[written_index]];
    Advance(progress,
            fmt::format("{} {}{}", fold.name, outcome.stem, outcome.ok ? "" : " (failed)"));
  };
  if (pipelined) {
    preparer = std::make_unique<BackgroundWorker>();
    writer = std::make_unique<BackgroundWorker>();
    prepared = preparer->Submit([&prepare] { prepare(0); });
  }
  for (size_t k = 0; k < todo.size() && !InterruptRequested(); ++k) {
    if (pipelined) {
      prepared.get();  // UsageError or bad_alloc of the preparer: rethrown here
      if (k + 1 < todo.size()) prepared = preparer->Submit([&prepare, k] { prepare(k + 1); });
    } else {
      prepare(k);
    }
    const TestView& test = fold.tests[todo[k]];
    ViewOutcome& outcome = views[todo[k]];
    const PreparedView& view = ws.views[k % 2];
    bool compared = false;
    if (!view.failure.empty()) {
      FailView(fold, test, view.failure, outcome);
    } else {
      try {
        CompareView(s, tally, ws, view, fold, test,
                    errors_later ? &ws.error_images[k % 2] : nullptr, outcome);
        compared = true;
      } catch (const UsageError&) {
        throw;
      } catch (const Error& e) {
        FailView(fold, test, e.what(), outcome);
      }
    }
    finish_write();  // view k-1's: its error images are the other set
    if (!compared) {
      Advance(progress, fmt::format("{} {} (failed)", fold.name, test.stem));
    } else if (pipelined) {
      written_index = k;
      written = writer->Submit([&write, k] { write(k); });
    } else {
      write(k);
      Advance(progress,
              fmt::format("{} {}{}", fold.name, test.stem, outcome.ok ? "" : " (failed)"));
    }
  }
  if (prepared.valid()) prepared.wait();  // interrupted: the prepared view stays unrecorded
  finish_write();
  tally.AddSeconds(&EvaluateTimings::views, Seconds(start));
}

}  // namespace rephoto::eval
