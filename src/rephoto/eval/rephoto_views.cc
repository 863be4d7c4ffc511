#include "rephoto/eval/rephoto_views.h"

#include "rephoto/compare/resample.h"
#include "rephoto/core/file.h"
#include "rephoto/core/process.h"
#include "rephoto/eval/command.h"
#include "rephoto/eval/keys.h"
#include "rephoto/eval/records.h"
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
const Image& EvalPhoto(RunState& s, ViewWorkspace& ws, const TestView& test, fs::path* used_path) {
  Image* scratch = &ws.eval_photo;
  const camera::Camera& full = s.scene.CameraOf(s.scene.views[test.view_index]);
  if (full.width == test.camera.width && full.height == test.camera.height) {
    io::ReadImage(test.photo, scratch);
    *used_path = test.photo;
    return *scratch;
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
          return *scratch;
        }
      }
    } catch (const Error&) {
      // recompute below
    }
  }
  Image& photo = ws.full_photo;
  io::ReadImage(test.photo, &photo);
  REPHOTO_CHECK(photo.width() == full.width && photo.height() == full.height,
                "{}: photo is {}x{} but its camera is {}x{}", test.photo.string(), photo.width(),
                photo.height(), full.width, full.height);
  compare::ResizeImage(photo, test.camera.width, test.camera.height, scratch);
  io::WritePngAndQuantize(cached, scratch, io::PngDepth::k16, io::PngCompression::kNone);
  WriteTextFileAtomically(key_file, key);
  ++s.counters.photos_downscaled;
  *used_path = cached;
  return *scratch;
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

// Gaussians: a pixel is the model's where its alpha reaches --min-alpha (the PNG's alpha, so a
// reused rendering gives the same mask).
Mask AlphaMask(const Image& render, double min_alpha) {
  Mask mask(render.width(), render.height(), 1);
  const float* px = render.data();
  const int channels = render.channels();
  uint8_t* m = mask.data();
  for (size_t i = 0, n = static_cast<size_t>(render.width()) * render.height(); i < n; ++i) {
    m[i] = channels == 4 && px[i * 4 + 3] >= static_cast<float>(min_alpha) ? 255 : 0;
  }
  return mask;
}

compare::CompareOptions CompareSettings(const EvaluateOptions& o) {
  compare::CompareOptions c;
  c.metrics = o.metrics;
  c.metric_options = o.metric_options;
  c.exposure = o.exposure;
  c.resize = o.resize;
  c.write_error_images = o.error_images;
  return c;
}

// The rendering of the view into ws.render: reused from disk, rendered, or the external one.
fs::path ObtainRendering(RunState& s, ViewWorkspace& ws, FoldState& fold, const TestView& test,
                         render::ViewRenderer* renderer, const ViewOutcome& outcome) {
  const fs::path renders_dir = fold.dir / "renders";
  if (outcome.reuse_render) {
    // Only compare settings changed: the rendering on disk is the one this view needs.
    io::ReadImage(renders_dir / (test.stem + ".png"), &ws.render);
    return renders_dir / (test.stem + ".png");
  }
  if (renderer != nullptr) {
    renderer->Render(test.camera, test.pose, &ws.rephoto);
    render::WriteRephoto(renders_dir, test.stem, &ws.rephoto);  // compared as the PNG written
    std::swap(ws.render, ws.rephoto.color);  // the next view renders into the previous buffer
    ++s.counters.views_rendered;
    return renders_dir / (test.stem + ".png");
  }
  const fs::path path = FindImageByStem(fold.out_dir, test.stem);
  REPHOTO_CHECK(!path.empty(), "{}: no rendering named '{}'", fold.out_dir.string(), test.stem);
  io::ReadImage(path, &ws.render);
  return path;
}

void EvaluateView(RunState& s, ViewWorkspace& ws, FoldState& fold, const TestView& test,
                  render::ViewRenderer* renderer, ViewOutcome* outcome) {
  auto start = Clock::now();
  const fs::path render_path = ObtainRendering(s, ws, fold, test, renderer, *outcome);
  outcome->render_seconds = Seconds(start);
  s.timings.render += outcome->render_seconds;

  start = Clock::now();
  const fs::path errors_dir = fold.dir / "errors";
  fs::path photo_path;
  const Image& photo = EvalPhoto(s, ws, test, &photo_path);
  const std::optional<Mask> mask = EvalMask(test);
  std::error_code ec;
  if (s.o.error_images) {
    RemoveStaleErrorImages(errors_dir, test.stem);
    fs::create_directories((errors_dir / test.stem).parent_path(), ec);
  }
  std::optional<Mask> render_mask;
  if (fold.gaussians && (renderer != nullptr || outcome->reuse_render)) {
    render_mask = AlphaMask(ws.render, s.o.min_alpha);
  }
  outcome->image = compare::ComparePhotoAndRender(
      CompareSettings(s.o), test.stem, photo_path, fs::path(s.Relative(render_path)), photo,
      ws.render, mask ? &*mask : nullptr, render_mask ? &*render_mask : nullptr, errors_dir,
      &ws.compare);
  outcome->compare_seconds = Seconds(start);
  s.timings.compare += outcome->compare_seconds;
  ++s.counters.views_compared;
  outcome->ok = true;
  WriteViewRecord(s, fold, *outcome);
}

}  // namespace

std::vector<size_t> PlanViews(RunState& s, FoldState& fold, Progress* progress, size_t first,
                              size_t count) {
  const bool external = s.source == ModelSource::kRender;
  const std::string compare_key = CompareSettingsKey(s.o);
  fold.views.resize(fold.tests.size());
  const size_t end = count == 0 ? fold.tests.size() : std::min(fold.tests.size(), first + count);
  std::vector<size_t> todo;
  for (size_t i = first; i < end; ++i) {
    const TestView& test = fold.tests[i];
    ViewOutcome& outcome = fold.views[i];
    outcome.stem = test.stem;
    outcome.name = test.name;
    outcome.record = fold.dir / "views" / (test.stem + ".json");
    std::string render_hash;
    if (external) {
      const fs::path image = FindImageByStem(fold.out_dir, test.stem);
      render_hash = image.empty() ? std::string() : s.hashes->Hash(image);
    }
    outcome.key = ViewKey(test, fold.base_key, render_hash, compare_key);
    const std::optional<Json> previous = run::ReadJsonRecord(outcome.record);  // read once
    if (!external) {
      outcome.render_key = RenderKey(fold.base_key, test);
      std::error_code ec;
      outcome.reuse_render =
          previous && previous->value("render_key", "") == outcome.render_key &&
          fs::is_regular_file(fold.dir / "renders" / (test.stem + ".png"), ec) &&
          fs::is_regular_file(fold.dir / "renders" / (test.stem + ".depth.exr"), ec);
    }
    if (ReadViewRecord(s, outcome.record, previous, outcome.key, &outcome)) {
      outcome.ok = true;
      outcome.reused = true;
      outcome.image.name = test.stem;
      ++s.counters.views_reused;
      Advance(progress, fmt::format("{} {} (done before)", fold.name, test.stem));
    } else {
      todo.push_back(i);
    }
  }
  return todo;
}

void EvaluateViews(RunState& s, ViewWorkspace& ws, FoldState& fold,
                   const std::vector<size_t>& todo, render::ViewRenderer* renderer,
                   Progress* progress) {
  for (size_t i : todo) {
    if (InterruptRequested()) break;
    const TestView& test = fold.tests[i];
    ViewOutcome& outcome = fold.views[i];
    try {
      EvaluateView(s, ws, fold, test, renderer, &outcome);
      Advance(progress, fmt::format("{} {}", fold.name, test.stem));
    } catch (const UsageError&) {
      throw;
    } catch (const Error& e) {
      outcome.ok = false;
      outcome.message = fmt::format("{} {}: {}", fold.name, test.stem, e.what());
      LogWarning(outcome.message);
      Advance(progress, fmt::format("{} {} (failed)", fold.name, test.stem));
    }
  }
}

}  // namespace rephoto::eval
