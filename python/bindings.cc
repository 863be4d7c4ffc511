// pybind11 module rephoto._rephoto: the library's own functions for Python (python/rephoto/
// __init__.py adds load_run and the pandas tables). Conventions:
// - Images from numpy: H x W (grey) or H x W x C with C in {1, 2, 3, 4}, dtype uint8 (v/255),
//   uint16 (v/65535) or float32 (as is; [0,1] expected), any strides. The library's Image owns
//   its memory (core/image.h), so every input is brought once, in one parallel pass, into the
//   form an image decoder gives: uint8 copied as 8-bit samples (Image8), float32 copied,
//   uint16 scaled to float. No other copy is made; compare then runs the CLI's own per-pair
//   function (compare::CompareInMemory). On 4000x3000 RGB inputs the copy costs 0.2-1 % of
//   the CLI's in-memory metric time for uint8 and 1.4 % (all metrics) to 6 % (psnr+ssim) for
//   float32 (python/bench/bench_compare.py, figures in README.md), under the 10 %
//   budget, so the owning Image was not given a non-owning view of foreign memory.
// - Images to numpy (error images, renderings): the library's buffers are moved into the
//   returned arrays (no copy), float32, H x W or H x W x C.
// - The GIL is released around every conversion and library call that touches pixels, files
//   or models, so Python threads run them concurrently.
// - rephoto::Error -> rephoto.Error (RuntimeError); rephoto::UsageError and bad arguments ->
//   rephoto.UsageError (both rephoto.Error and ValueError); messages are the CLI's lines.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "rephoto/compare/compare.h"
#include "rephoto/compare/compat_compare.h"
#include "rephoto/lpips/lpips.h"
#include "rephoto/core/error.h"
#include "rephoto/core/isa.h"
#include "rephoto/core/limits.h"
#include "rephoto/core/image.h"
#include "rephoto/core/parallel.h"
#include "rephoto/eval/evaluate.h"
#include "rephoto/eval/settings.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/metrics/compat.h"
#include "rephoto/metrics/metrics.h"
#include "rephoto/render/render.h"
#include "rephoto/render/render_model.h"
#include "rephoto/representation/make_renderer.h"
#include "rephoto/run/run_data.h"
#include "rephoto/scene/read_scene.h"
#include "rephoto/splat/gaussians.h"
#include "rephoto/splat/rasterize.h"
#include "rephoto/split/split.h"

namespace py = pybind11;

namespace rephoto::python {
namespace {

// ------------------------------------------------------------------------------ arrays

enum class Sample { kUint8, kUint16, kFloat32 };

// A numpy image as seen by the converters: pointer, shape and byte strides. Holds a reference
// to the array so that the pointer stays valid while the GIL is released.
struct ArrayView {
  py::array array;
  const char* data = nullptr;
  Sample sample = Sample::kFloat32;
  int height = 0, width = 0, channels = 1;
  py::ssize_t stride_y = 0, stride_x = 0, stride_c = 0;
};

ArrayView ViewImage(const py::handle& object, const char* what, bool is_mask = false) {
  py::array array = py::array::ensure(object);
  if (!array) throw UsageError(fmt::format("{}: expected a numpy array", what));
  ArrayView v;
  v.array = array;
  const py::dtype dtype = array.dtype();
  const char kind = dtype.kind();
  if (is_mask && (kind == 'b' || (kind == 'u' && dtype.itemsize() == 1))) {
    v.sample = Sample::kUint8;
  } else if (kind == 'u' && dtype.itemsize() == 1) {
    v.sample = Sample::kUint8;
  } else if (kind == 'u' && dtype.itemsize() == 2) {
    v.sample = Sample::kUint16;
  } else if (kind == 'f' && dtype.itemsize() == 4) {
    v.sample = Sample::kFloat32;
  } else {
    throw UsageError(fmt::format("{}: dtype {} is not supported ({})", what,
                                 std::string(py::str(py::object(dtype))),
                                 is_mask ? "bool or uint8" : "uint8, uint16 or float32"));
  }
  const int ndim = static_cast<int>(array.ndim());
  if (ndim != 2 && !(ndim == 3 && !is_mask)) {
    throw UsageError(fmt::format("{}: expected {} array, got {} dimensions", what,
                                 is_mask ? "an H x W" : "an H x W or H x W x C", ndim));
  }
  // The shape as numpy gives it (64-bit), checked before it is narrowed: a side of 2^32 + 16
  // must not become 16, and the pixel count obeys the limit image files obey (core/limits.h).
  const py::ssize_t height = array.shape(0), width = array.shape(1);
  const py::ssize_t channels = ndim == 3 ? array.shape(2) : 1;
  if (channels < 1 || channels > 4) {
    throw UsageError(fmt::format("{}: {} channels (1 to 4 supported: grey, grey+alpha, RGB, RGBA)",
                                 what, channels));
  }
  if (height == 0 || width == 0) throw UsageError(fmt::format("{}: empty image", what));
  if (static_cast<uint64_t>(width) > static_cast<uint64_t>(std::numeric_limits<int>::max()) ||
      static_cast<uint64_t>(height) > static_cast<uint64_t>(std::numeric_limits<int>::max()) ||
      static_cast<uint64_t>(width) * static_cast<uint64_t>(height) > MaxPixels()) {
    throw Error(fmt::format("{}: image of {}x{} pixels is larger than the limit of {} pixels "
                            "(rephoto's --max-pixels)",
                            what, width, height, MaxPixels()));
  }
  v.height = static_cast<int>(height);
  v.width = static_cast<int>(width);
  v.channels = static_cast<int>(channels);
  v.data = static_cast<const char*>(array.data());
  v.stride_y = array.strides(0);
  v.stride_x = array.strides(1);
  v.stride_c = ndim == 3 ? array.strides(2) : 0;
  return v;
}

template <typename T>
float Scaled(const char* p) {
  T value;
  std::memcpy(&value, p, sizeof(T));
  // Divisions, as io/image_io.cc does: v * (1/255) differs in the last bit for some v.
  if constexpr (std::is_same_v<T, uint8_t>) return static_cast<float>(value) / 255.f;
  if constexpr (std::is_same_v<T, uint16_t>) return static_cast<float>(value) / 65535.f;
  if constexpr (std::is_same_v<T, float>) return value;
}

// The array as the decoder of an image file of that sample type would give it, all channels
// kept: uint8 as 8-bit samples (Image8, v standing for v / 255, as io::ReadImage8 keeps JPEG and
// 8-bit PNG), uint16 scaled to floats (v / 65535, as io::ReadImage does), float32 as is. Packed
// rows (C-contiguous, or only the rows padded) are one memcpy (uint8, float32) or one
// vectorisable loop (uint16) per row. Call without the GIL.
template <typename In, typename Out>
void Convert(const ArrayView& v, ImageT<Out>* image) {
  static_assert(std::is_same_v<Out, float> || std::is_same_v<In, Out>);
  image->Resize(v.width, v.height, v.channels);
  const bool packed = (v.channels == 1 || v.stride_c == static_cast<py::ssize_t>(sizeof(In))) &&
                      v.stride_x == static_cast<py::ssize_t>(v.channels * sizeof(In));
  const size_t n = static_cast<size_t>(v.width) * v.channels;
  ParallelFor(0, v.height, 16, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      const char* row = v.data + y * v.stride_y;
      Out* out = image->row(static_cast<int>(y));
      if (packed) {
        if constexpr (std::is_same_v<In, Out>) {
          std::memcpy(out, row, n * sizeof(Out));
        } else {
          const In* in = reinterpret_cast<const In*>(row);  // numpy aligns its buffers
          for (size_t i = 0; i < n; ++i) out[i] = static_cast<float>(in[i]) / 65535.f;
        }
      } else {
        for (int x = 0; x < v.width; ++x) {
          for (int c = 0; c < v.channels; ++c) {
            const char* p = row + x * v.stride_x + c * v.stride_c;
            if constexpr (std::is_same_v<In, Out>) {
              std::memcpy(&out[x * v.channels + c], p, sizeof(In));
            } else {
              out[x * v.channels + c] = Scaled<In>(p);
            }
          }
        }
      }
    }
  });
}

// A converted input: 8-bit samples or floats.
struct Decoded {
  Image8 bytes;
  Image floats;
  bool is_8bit = false;
};

void Decode(const ArrayView& v, Decoded* out) {
  out->is_8bit = v.sample == Sample::kUint8;
  switch (v.sample) {
    case Sample::kUint8:
      return Convert<uint8_t>(v, &out->bytes);
    case Sample::kUint16:
      return Convert<uint16_t>(v, &out->floats);
    case Sample::kFloat32:
      return Convert<float>(v, &out->floats);
  }
}

// compare::CompareInMemory on the decoded pair, whichever sample types they hold.
compare::ImageResult CompareDecoded(const compare::CompareOptions& options, const Decoded& photo,
                                    const Decoded& render, const Mask* photo_mask,
                                    const Mask* render_mask, std::vector<Image>* errors,
                                    compare::CompareWorkspace* workspace) {
  const auto run = [&](const auto& p, const auto& r) {
    return compare::CompareInMemory(options, p, r, photo_mask, render_mask, errors, workspace);
  };
  if (photo.is_8bit) {
    return render.is_8bit ? run(photo.bytes, render.bytes) : run(photo.bytes, render.floats);
  }
  return render.is_8bit ? run(photo.floats, render.bytes) : run(photo.floats, render.floats);
}

// Non-zero = valid.
void ToMask(const ArrayView& v, Mask* mask) {
  mask->Resize(v.width, v.height, 1);
  for (int y = 0; y < v.height; ++y) {
    const char* row = v.data + y * v.stride_y;
    uint8_t* out = mask->row(y);
    for (int x = 0; x < v.width; ++x) out[x] = row[x * v.stride_x] != 0 ? 1 : 0;
  }
}

// Moves `image` into a float32 numpy array without copying its pixels.
py::array ToNumpy(Image&& image) {
  auto* owner = new Image(std::move(image));
  py::capsule free(owner, [](void* p) { delete static_cast<Image*>(p); });
  const py::ssize_t h = owner->height(), w = owner->width(), c = owner->channels();
  if (c == 1) return py::array_t<float>({h, w}, {w * 4, py::ssize_t(4)}, owner->data(), free);
  return py::array_t<float>({h, w, c}, {w * c * 4, c * 4, py::ssize_t(4)}, owner->data(), free);
}

// ------------------------------------------------------------------------------ compare

std::vector<metrics::Metric> MetricList(const py::object& metrics) {
  if (metrics.is_none()) return metrics::AllMetrics();
  if (py::isinstance<py::str>(metrics))
    return metrics::ParseMetricList(metrics.cast<std::string>());
  std::vector<metrics::Metric> list;
  for (const py::handle& item : metrics) {
    const std::string name = py::str(item);
    const std::optional<metrics::Metric> metric = metrics::ParseMetric(name);
    if (!metric) {
      throw UsageError(
          fmt::format("unknown metric '{}' (1-ncc, cb+cr, zssd, dssim, census, "
                      "icid, psnr, ssim, lpips)",
                      name));
    }
    list.push_back(*metric);
  }
  return list;
}

// Buffers reused from call to call on the same thread (first touch of fresh pages is costly).
struct ThreadBuffers {
  Decoded photo, render;
  Mask user_mask, render_mask;
  compare::CompareWorkspace workspace;
};

py::dict Compare(const py::object& photo_object, const py::object& render_object,
                 const py::object& mask_object, const py::object& metrics_object,
                 const py::object& render_mask_object, bool error_images, int window,
                 const std::string& ssim_mode, float dark, float saturated,
                 const std::optional<std::string>& compat, std::array<float, 3> background,
                 bool resize, double min_alpha, const std::optional<std::string>& lpips_weights,
                 const std::string& lpips_net) {
  compare::CompareOptions options;
  if (lpips_weights) options.lpips_weights = *lpips_weights;
  const std::optional<lpips::LpipsNet> net = lpips::ParseLpipsNet(lpips_net);
  REPHOTO_CHECK_USAGE(net.has_value(), "lpips_net: '{}' is not alex or vgg", lpips_net);
  options.lpips_net = *net;
  REPHOTO_CHECK_USAGE(min_alpha >= 0 && min_alpha <= 1, "min_alpha: {} is not in [0, 1]",
                      min_alpha);
  REPHOTO_CHECK_USAGE(!compat || min_alpha == 0, "compat: min_alpha does not apply (no masks)");
  options.min_alpha = min_alpha;
  options.metrics = MetricList(metrics_object);
  options.metric_options.window = window;
  REPHOTO_CHECK_USAGE(window >= 3 && window % 2 == 1, "window: {} is not an odd number >= 3",
                      window);
  if (ssim_mode == "skimage") {
    options.metric_options.ssim_gaussian = false;
    options.metric_options.ssim_window = 7;
  } else {
    REPHOTO_CHECK_USAGE(ssim_mode == "gaussian", "ssim_mode: '{}' is not gaussian or skimage",
                        ssim_mode);
  }
  options.exposure.dark_threshold = dark;
  options.exposure.saturated_threshold = saturated;
  options.resize = resize;
  options.write_error_images = false;
  const ArrayView photo = ViewImage(photo_object, "photo");
  const ArrayView render = ViewImage(render_object, "render");
  REPHOTO_CHECK_USAGE(resize || (photo.width == render.width && photo.height == render.height),
                      "render is {}x{} but photo is {}x{} (same size required, or resize=True)",
                      render.width, render.height, photo.width, photo.height);
  std::optional<ArrayView> mask, render_mask;
  if (!mask_object.is_none()) mask = ViewImage(mask_object, "mask", true);
  if (!render_mask_object.is_none())
    render_mask = ViewImage(render_mask_object, "render_mask", true);
  REPHOTO_CHECK_USAGE(!mask || (mask->width == photo.width && mask->height == photo.height),
                      "mask is {}x{} but photo is {}x{}", mask ? mask->width : 0,
                      mask ? mask->height : 0, photo.width, photo.height);
  REPHOTO_CHECK_USAGE(
      !render_mask || (render_mask->width == render.width && render_mask->height == render.height),
      "render_mask is {}x{} but render is {}x{}", render_mask ? render_mask->width : 0,
      render_mask ? render_mask->height : 0, render.width, render.height);
  if (compat) {
    const std::optional<metrics::CompatPreset> preset = metrics::ParseCompatPreset(*compat);
    REPHOTO_CHECK_USAGE(preset.has_value(), "compat: '{}' is not 3dgs or nerfstudio", *compat);
    REPHOTO_CHECK_USAGE(!mask && !render_mask, "compat {}: masks do not exist in this mode",
                        *compat);
    // The preset's metrics unless `metrics` names some (compare/compat_compare.h).
    options.metrics = compare::ResolveCompatMetrics(
        *preset, metrics_object.is_none() ? std::vector<metrics::Metric>{} : options.metrics,
        options.lpips_weights);
    options.compat = preset;
    options.compat_background = background;
  }

  // The arrays as a decoder would give them (one copy or conversion each, into buffers kept
  // by the thread), then the CLI's own per-pair function (compare::CompareInMemory).
  thread_local ThreadBuffers buffers;
  ThreadBuffers& b = buffers;
  compare::ImageResult result;
  std::vector<Image> errors;
  {
    py::gil_scoped_release release;
    Decode(photo, &b.photo);
    Decode(render, &b.render);
    if (mask) ToMask(*mask, &b.user_mask);
    if (render_mask) ToMask(*render_mask, &b.render_mask);
    result = CompareDecoded(options, b.photo, b.render, mask ? &b.user_mask : nullptr,
                            render_mask ? &b.render_mask : nullptr,
                            error_images ? &errors : nullptr, &b.workspace);
  }
  py::dict out, evaluated, error_arrays;
  out["completeness"] = result.completeness.value;
  if (!compat) {
    out["valid_photo_windows"] = result.completeness.valid_photo;
    out["valid_both_windows"] = result.completeness.valid_both;
    out["resized"] = result.resized;
  }
  for (size_t i = 0; i < options.metrics.size(); ++i) {
    const std::string name(metrics::MetricName(options.metrics[i]));
    out[name.c_str()] = result.metrics[i].mean;
    evaluated[name.c_str()] = result.metrics[i].evaluated;
    if (error_images) error_arrays[name.c_str()] = ToNumpy(std::move(errors[i]));
  }
  out["evaluated"] = evaluated;
  if (error_images) out["errors"] = error_arrays;
  return out;
}

// ------------------------------------------------------------------------------ scenes

py::array PoseMatrix(const camera::Pose& pose) {
  py::array_t<double> m({4, 4});
  auto r = m.mutable_unchecked<2>();
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) r(i, j) = 0;
  }
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r(i, j) = pose.rotation(i, j);
    r(i, 3) = pose.translation(i);
  }
  r(3, 3) = 1;
  return m;
}

camera::Pose PoseFromMatrix(const py::handle& object) {
  const py::array_t<double, py::array::c_style | py::array::forcecast> m =
      py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(object);
  REPHOTO_CHECK_USAGE(m && m.ndim() == 2 && m.shape(0) >= 3 && m.shape(1) == 4,
                      "cam_from_world: expected a 4x4 (or 3x4) matrix");
  camera::Pose pose;
  auto r = m.unchecked<2>();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) pose.rotation(i, j) = r(i, j);
    pose.translation(i) = r(i, 3);
  }
  pose.Validate("cam_from_world");
  return pose;
}

struct PyView {
  std::string name;
  std::filesystem::path image_path;
  std::optional<std::filesystem::path> mask_path;
  int camera_id = 0;
  camera::Camera camera;
  camera::Pose pose;
};

struct PyScene {
  scene::Scene scene;
  std::string format;
  std::filesystem::path source;
  std::vector<PyView> views;
};

std::shared_ptr<PyScene> ReadScene(const std::filesystem::path& path,
                                   const std::optional<std::string>& format,
                                   const std::optional<std::filesystem::path>& image_root,
                                   bool check_image_sizes) {
  scene::ReadSceneOptions options;
  if (format) {
    options.format = scene::ParseSceneFormat(*format);
    REPHOTO_CHECK_USAGE(options.format.has_value(), "format: unknown scene format '{}' ({})",
                        *format, scene::SceneFormatList());
  }
  options.image_root = image_root;
  options.check_image_sizes = check_image_sizes;
  auto result = std::make_shared<PyScene>();
  scene::SceneSource source;
  {
    py::gil_scoped_release release;
    result->scene = scene::ReadScene(path, options, &source);
  }
  result->format = std::string(scene::SceneFormatName(source.format));
  result->source = source.path;
  for (const scene::View& view : result->scene.views) {
    result->views.push_back({view.name, view.image_path, view.mask_path, view.camera_id,
                             result->scene.CameraOf(view), view.cam_from_world});
  }
  return result;
}

py::dict Split(const py::object& scene_or_names, const std::string& scheme_text,
               std::optional<uint64_t> seed) {
  std::vector<std::string> names;
  if (py::isinstance<PyScene>(scene_or_names)) {
    for (const PyView& view : scene_or_names.cast<const PyScene&>().views)
      names.push_back(view.name);
  } else {
    for (const py::handle& item : scene_or_names) names.push_back(py::str(item));
  }
  split::Scheme scheme = split::ParseScheme(scheme_text);
  if (seed) {
    REPHOTO_CHECK_USAGE(scheme.Seeded(), "seed: scheme '{}' takes no seed", scheme_text);
    scheme.seed = *seed;
  }
  const split::Split split = split::MakeSplit(names, scheme);
  py::list folds;
  for (const split::Fold& fold : split.folds) {
    py::dict f;
    f["train"] = fold.train;
    f["test"] = fold.test;
    folds.append(f);
  }
  py::dict out;
  out["scheme"] = split.scheme.ToString();
  out["cross_validated"] = split.cross_validated;
  out["folds"] = folds;
  return out;
}

// ------------------------------------------------------------------------------ models

// A model file as `rephoto render MODEL` (representation auto) renders it: resolved and read by
// the library's renderer factory (representation/make_renderer.h).
struct Model {
  std::filesystem::path path;
  // kAuto (a mesh or point cloud in models.mesh) or kGaussians (models.gaussians).
  render::ViewRepresentation resolved = render::ViewRepresentation::kAuto;
  representation::Models models;
};

std::shared_ptr<Model> LoadModel(const std::filesystem::path& path, float point_radius) {
  auto model = std::make_shared<Model>();
  model->path = path;
  py::gil_scoped_release release;
  representation::RendererSettings settings;
  if (point_radius > 0) settings.model.point_radius = point_radius;
  model->resolved = representation::ResolveRepresentation(render::ViewRepresentation::kAuto, path);
  model->models = representation::LoadModels(model->resolved, path, settings);
  return model;
}

py::tuple Render(const Model& model, const py::object& view_or_camera,
                 const py::object& cam_from_world, int spp, uint32_t seed, bool backfaces,
                 std::array<float, 3> background, const std::string& gaussian_mode) {
  camera::Camera camera;
  camera::Pose pose;
  if (py::isinstance<PyView>(view_or_camera)) {
    const PyView& view = view_or_camera.cast<const PyView&>();
    camera = view.camera;
    pose = cam_from_world.is_none() ? view.pose : PoseFromMatrix(cam_from_world);
  } else {
    camera = view_or_camera.cast<camera::Camera>();
    REPHOTO_CHECK_USAGE(!cam_from_world.is_none(),
                        "render: cam_from_world is required with a Camera (or pass a View)");
    pose = PoseFromMatrix(cam_from_world);
  }
  camera.Validate("camera");
  representation::RendererSettings settings;
  settings.render.samples_per_pixel = spp;
  settings.render.seed = seed;
  settings.render.backfaces = backfaces;
  settings.gaussians.background = Eigen::Vector3f(background[0], background[1], background[2]);
  settings.gaussians.mode = representation::GaussianModeFromName(gaussian_mode, "gaussian_mode");
  render::Rephoto rephoto;
  {
    py::gil_scoped_release release;
    representation::MakeRenderer(model.resolved, model.models, {}, settings)
        ->Render(camera, pose, &rephoto);
  }
  return py::make_tuple(ToNumpy(std::move(rephoto.color)), ToNumpy(std::move(rephoto.depth)));
}

// ------------------------------------------------------------------------------ evaluate

eval::SettingValue ToSetting(const py::handle& value, const std::string& name) {
  if (py::isinstance<py::bool_>(value)) return value.cast<bool>();
  if (py::isinstance<py::int_>(value)) return value.cast<int64_t>();
  if (py::isinstance<py::float_>(value)) return value.cast<double>();
  if (py::isinstance<py::str>(value)) return value.cast<std::string>();
  if (py::hasattr(value, "__fspath__")) return std::string(py::str(value.attr("__fspath__")()));
  if (py::isinstance<py::sequence>(value)) {
    std::vector<std::string> items;
    for (const py::handle& item : value) items.push_back(py::str(item));
    return items;
  }
  throw UsageError(fmt::format("{}: unsupported value type {}", name,
                               std::string(py::str(value.get_type().attr("__name__")))));
}

std::filesystem::path Evaluate(const py::kwargs& kwargs) {
  eval::EvaluateOptions options;
  if (kwargs.contains("config")) {
    eval::LoadConfigFile(std::filesystem::path(std::string(
                             py::str(py::module_::import("os").attr("fspath")(kwargs["config"])))),
                         &options);
  }
  for (const auto& [key, value] : kwargs) {
    std::string name = py::str(key);
    if (name == "config") continue;
    if (value.is_none()) continue;
    eval::ApplySetting(&options, name, ToSetting(value, name), name);
  }
  py::gil_scoped_release release;
  eval::RunEvaluate(options);
  return options.out;
}

// A run folder's tables as run::LoadRun reads them (run/run_table.h: one rule for C++ and
// Python): {"layout": "evaluate"|"compare", "per_image": [row...], "per_fold": [row...]}, each row
// a dict of column -> str | int | float (NaN where nothing was evaluated), in file order.
py::dict LoadRunTables(const std::filesystem::path& dir) {
  const run::RunData data = [&] {
    py::gil_scoped_release release;
    return run::LoadRun(dir);
  }();
  const auto rows = [](const run::RunTable& table) {
    py::list list;
    for (const std::vector<run::Cell>& cells : table.rows) {
      py::dict row;
      for (size_t c = 0; c < table.columns.size(); ++c) {
        std::visit([&](const auto& value) { row[py::str(table.columns[c])] = py::cast(value); },
                   cells[c]);
      }
      list.append(std::move(row));
    }
    return list;
  };
  py::dict out;
  out["layout"] = data.layout == run::RunLayout::kEvaluate ? "evaluate" : "compare";
  out["per_image"] = rows(data.image_table);
  out["per_fold"] = rows(data.fold_table);
  return out;
}

// For the timing comparison (python/bench/bench_compare.py): seconds per call of the CLI's
// own per-pair function (compare::CompareInMemory = ComparePhotoAndRender without file paths,
// no error images) on these arrays as a decoder would give them (uint8 as 8-bit samples, as the
// CLI keeps JPEG and 8-bit PNG; others as floats), converted once outside the timing. The
// workspace is reused between repeats, as the CLI does between pairs; returns the median.
double CliPairSeconds(const py::object& photo_object, const py::object& render_object,
                      const py::object& metrics_object, int repeats) {
  compare::CompareOptions options;
  options.metrics = MetricList(metrics_object);
  options.write_error_images = false;
  const ArrayView photo_view = ViewImage(photo_object, "photo");
  const ArrayView render_view = ViewImage(render_object, "render");
  Decoded photo, render;
  py::gil_scoped_release release;
  Decode(photo_view, &photo);
  Decode(render_view, &render);
  compare::CompareWorkspace workspace;
  std::vector<double> seconds;
  for (int i = 0; i < std::max(repeats, 1); ++i) {
    const auto start = std::chrono::steady_clock::now();
    CompareDecoded(options, photo, render, nullptr, nullptr, nullptr, &workspace);
    seconds.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  std::sort(seconds.begin(), seconds.end());
  return seconds[seconds.size() / 2];
}

// For the timing comparison: seconds (median of `repeats`) of the one copy or conversion
// rephoto.compare makes of this array (Decode into a buffer reused between repeats).
double DecodeSeconds(const py::object& object, int repeats) {
  const ArrayView view = ViewImage(object, "array");
  py::gil_scoped_release release;
  Decoded decoded;
  std::vector<double> seconds;
  for (int i = 0; i < std::max(repeats, 1) + 1; ++i) {  // the first call touches fresh pages
    const auto start = std::chrono::steady_clock::now();
    Decode(view, &decoded);
    seconds.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  seconds.erase(seconds.begin());
  std::sort(seconds.begin(), seconds.end());
  return seconds[seconds.size() / 2];
}

}  // namespace
}  // namespace rephoto::python

PYBIND11_MODULE(_rephoto, m) {
  using namespace rephoto;
  using namespace rephoto::python;
  m.doc() = "rephoto's C++ library (see the rephoto package for the documented API)";

  static py::exception<Error> error(m, "Error", PyExc_RuntimeError);
  static py::object usage_error = [&] {
    py::object type = py::reinterpret_steal<py::object>(PyErr_NewException(
        "rephoto.UsageError", py::make_tuple(error, py::handle(PyExc_ValueError)).ptr(), nullptr));
    m.attr("UsageError") = type;
    return type;
  }();
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const UsageError& e) {
      PyErr_SetString(usage_error.ptr(), e.what());
    } catch (const Error& e) {
      PyErr_SetString(error.ptr(), e.what());
    }
  });

  m.attr("__version__") = compare::ToolVersion();
#ifdef NDEBUG
  m.attr("_build_type") = "Release";
#else
  m.attr("_build_type") = "Debug";
#endif
  m.attr("_compiler") = __VERSION__;
  // The instruction-set path (core/isa.h); a bad REPHOTO_ISA fails the import (ImportError
  // with the one-line message naming it).
  core::CheckIsaEnvironment();
  m.attr("_isa") = std::string(core::IsaName(core::ActiveIsa()));

  m.def("compare", &Compare, py::arg("photo"), py::arg("render"), py::arg("mask") = py::none(),
        py::arg("metrics") = py::none(), py::arg("render_mask") = py::none(),
        py::arg("error_images") = false, py::arg("window") = 9, py::arg("ssim_mode") = "gaussian",
        py::arg("dark") = 0.0f, py::arg("saturated") = 1.0f, py::arg("compat") = py::none(),
        py::arg("background") = std::array<float, 3>{0, 0, 0}, py::arg("resize") = false,
        py::arg("min_alpha") = 0.0, py::arg("lpips_weights") = py::none(),
        py::arg("lpips_net") = "alex");
  m.def("metric_names", [] {
    std::vector<std::string> names;
    for (metrics::Metric metric : metrics::AllMetrics())
      names.emplace_back(metrics::MetricName(metric));
    return names;
  });

  py::class_<camera::Camera>(m, "Camera")
      .def(
          py::init([](const std::string& model, int width, int height, std::vector<double> params) {
            camera::Camera c;
            const auto parsed = camera::ParseCameraModel(model);
            REPHOTO_CHECK_USAGE(parsed.has_value(), "camera model '{}' is unknown", model);
            c.model = *parsed;
            c.width = width;
            c.height = height;
            c.params = std::move(params);
            c.Validate("camera");
            return c;
          }),
          py::arg("model"), py::arg("width"), py::arg("height"), py::arg("params"))
      .def_property_readonly(
          "model",
          [](const camera::Camera& c) { return std::string(camera::CameraModelName(c.model)); })
      .def_readonly("width", &camera::Camera::width)
      .def_readonly("height", &camera::Camera::height)
      .def_readonly("params", &camera::Camera::params)
      .def("__repr__", [](const camera::Camera& c) {
        return fmt::format("Camera({}, {}x{}, {} params)", camera::CameraModelName(c.model),
                           c.width, c.height, c.params.size());
      });

  py::class_<PyView>(m, "View")
      .def_readonly("name", &PyView::name)
      .def_readonly("image_path", &PyView::image_path)
      .def_readonly("mask_path", &PyView::mask_path)
      .def_readonly("camera_id", &PyView::camera_id)
      .def_readonly("camera", &PyView::camera)
      .def_property_readonly("width", [](const PyView& v) { return v.camera.width; })
      .def_property_readonly("height", [](const PyView& v) { return v.camera.height; })
      .def_property_readonly("cam_from_world", [](const PyView& v) { return PoseMatrix(v.pose); })
      .def_property_readonly("center",
                             [](const PyView& v) {
                               const Eigen::Vector3d c = v.pose.Center();
                               return std::vector<double>{c.x(), c.y(), c.z()};
                             })
      .def("__repr__", [](const PyView& v) {
        return fmt::format("View('{}', {}x{} {})", v.name, v.camera.width, v.camera.height,
                           camera::CameraModelName(v.camera.model));
      });

  py::class_<PyScene, std::shared_ptr<PyScene>>(m, "Scene")
      .def_readonly("views", &PyScene::views)
      .def_readonly("format", &PyScene::format)
      .def_readonly("source", &PyScene::source)
      .def_property_readonly("image_root", [](const PyScene& s) { return s.scene.image_root; })
      .def_property_readonly("cameras", [](const PyScene& s) { return s.scene.cameras; })
      .def_property_readonly("point_count", [](const PyScene& s) { return s.scene.points.size(); })
      .def("__len__", [](const PyScene& s) { return s.views.size(); })
      .def("__getitem__",
           [](const PyScene& s, py::object key) -> PyView {
             if (py::isinstance<py::int_>(key)) {
               py::ssize_t i = key.cast<py::ssize_t>();
               const py::ssize_t n = static_cast<py::ssize_t>(s.views.size());
               if (i < 0) i += n;
               if (i < 0 || i >= n) throw py::index_error("view index out of range");
               return s.views[static_cast<size_t>(i)];
             }
             const std::string name = py::str(key);
             for (const PyView& v : s.views) {
               if (v.name == name) return v;
             }
             throw py::key_error(name);
           })
      .def("__repr__", [](const PyScene& s) {
        return fmt::format("Scene({} views, {} cameras, {} points, {} from {})", s.views.size(),
                           s.scene.cameras.size(), s.scene.points.size(), s.format,
                           s.source.string());
      });

  m.def("read_scene", &ReadScene, py::arg("path"), py::arg("format") = py::none(),
        py::arg("image_root") = py::none(), py::arg("check_image_sizes") = true);
  m.def("split", &Split, py::arg("scene"), py::arg("scheme"), py::arg("seed") = py::none());

  py::class_<Model, std::shared_ptr<Model>>(m, "Model")
      .def_readonly("path", &Model::path)
      .def_property_readonly("kind",
                             [](const Model& model) -> std::string {
                               if (model.models.gaussians) return "gaussians";
                               return model.models.mesh->representation() ==
                                              render::Representation::kPointCloud
                                          ? "point_cloud"
                                          : "mesh";
                             })
      .def("render", &Render, py::arg("view"), py::arg("cam_from_world") = py::none(),
           py::arg("spp") = 4, py::arg("seed") = 0, py::arg("backfaces") = true,
           py::arg("background") = std::array<float, 3>{0, 0, 0},
           py::arg("gaussian_mode") = "classic");
  m.def("load_model", &LoadModel, py::arg("path"), py::arg("point_radius") = 0.0f);
  m.def("evaluate", &Evaluate);
  m.def("_load_run_tables", &LoadRunTables, py::arg("path"));
  m.def("_decode_seconds", &DecodeSeconds, py::arg("array"), py::arg("repeats") = 5);
  m.def("_cli_pair_seconds", &CliPairSeconds, py::arg("photo"), py::arg("render"),
        py::arg("metrics") = py::none(), py::arg("repeats") = 3);
}
