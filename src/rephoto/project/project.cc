#include "rephoto/project/project.h"

#include <fmt/format.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <set>

#include "rephoto/core/colormap.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/image.h"
#include "rephoto/core/parallel.h"
#include "rephoto/core/progress.h"
#include "rephoto/core/stats.h"
#include "rephoto/io/image_io.h"
#include "rephoto/render/render.h"
#include "rephoto/render/visibility.h"
#include "rephoto/scene/image_name.h"

namespace rephoto::project {
namespace {

namespace fs = std::filesystem;

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

std::string ViewLabel(const ProjectView& view) {
  return view.name.empty() ? view.error_image.string() : view.name;
}

void CheckOptions(const ProjectOptions& options) {
  REPHOTO_CHECK(options.low_percentile >= 0 && options.low_percentile <= options.high_percentile &&
                    options.high_percentile <= 100,
                "project: percentiles {} and {} must satisfy 0 <= low <= high <= 100",
                options.low_percentile, options.high_percentile);
  REPHOTO_CHECK(std::isfinite(options.depth_tolerance) && options.depth_tolerance >= 0,
                "project: depth tolerance {} must be finite and >= 0", options.depth_tolerance);
  REPHOTO_CHECK(std::isfinite(options.footprint_tolerance) && options.footprint_tolerance >= 0,
                "project: footprint tolerance {} must be finite and >= 0",
                options.footprint_tolerance);
  if (options.fixed_range) {
    REPHOTO_CHECK(
        std::isfinite(options.fixed_range->first) && std::isfinite(options.fixed_range->second),
        "project: colour range [{}, {}] must be finite", options.fixed_range->first,
        options.fixed_range->second);
  }
}

// The camera an error image of size width x height is sampled with: the view's own, or (when
// allowed) the view's camera scaled to the image when only the resolution differs (aspect
// ratios within 1 %). Throws Error naming the image otherwise.
camera::Camera CameraForImage(const ProjectView& view, int width, int height, int channels,
                              const ProjectOptions& options) {
  REPHOTO_CHECK(channels == 1, "{}: error image has {} channels, expected 1",
                view.error_image.string(), channels);
  if (width == view.camera.width && height == view.camera.height) return view.camera;
  const double aspect_image = static_cast<double>(width) / height;
  const double aspect_camera = static_cast<double>(view.camera.width) / view.camera.height;
  REPHOTO_CHECK(options.scale_cameras && std::abs(aspect_image / aspect_camera - 1) <= 0.01,
                "{}: image is {}x{} but its camera is {}x{}{}", view.error_image.string(), width,
                height, view.camera.width, view.camera.height,
                options.scale_cameras ? " (another aspect ratio)" : "");
  return view.camera.Scaled(width, height);
}

// Checks every view's camera, pose and error image header before any work is done.
void CheckViews(const std::vector<ProjectView>& views, const ProjectOptions& options) {
  for (const ProjectView& view : views) {
    const std::string label = ViewLabel(view);
    view.camera.Validate(label);
    view.cam_from_world.Validate(label);
    const io::ImageHeader header = io::ReadImageHeader(view.error_image);
    CameraForImage(view, header.width, header.height, header.channels, options);
    if (!view.depth_image.empty()) {
      const io::ImageHeader depth = io::ReadImageHeader(view.depth_image);
      REPHOTO_CHECK(
          depth.channels == 1 && depth.width == header.width && depth.height == header.height,
          "{}: depth image is {}x{} with {} channels, expected {}x{} with 1 (the size "
          "of {})",
          view.depth_image.string(), depth.width, depth.height, depth.channels, header.width,
          header.height, view.error_image.string());
    }
  }
}

// What one view gives one vertex.
struct Sample {
  bool visible = false;    // passes the visibility test
  double error = 0;        // valid when has_error
  bool has_error = false;  // some qualifying pixel had a finite error
};

// Everything fixed for one view.
struct ViewContext {
  const render::ViewGeometry& geometry;  // camera, pose and usable field (render/visibility.h)
  const render::CameraRays& rays;
  const Image& depth;
  const Image& error;
  double relative_tolerance;  // depth_tolerance + footprint_tolerance / f
  double fx, fy;
};

// Barycentric weights of a face's sample points: the centroids of the 4 triangles of its
// midpoint subdivision (equal areas, so the mean over them is an area-uniform estimate).
constexpr double kFaceSamples[4][3] = {{1.0 / 3, 1.0 / 3, 1.0 / 3},
                                       {2.0 / 3, 1.0 / 6, 1.0 / 6},
                                       {1.0 / 6, 2.0 / 3, 1.0 / 6},
                                       {1.0 / 6, 1.0 / 6, 2.0 / 3}};

inline bool DepthAgrees(float d, double z, double tolerance) {
  return std::isfinite(d) && std::abs(z - static_cast<double>(d)) <= tolerance;
}

Sample SampleVertex(const ViewContext& view, const Eigen::Vector3d& world, double radius) {
  Sample sample;
  // Steps 1-2 of render/visibility.h's rule (the usable field, inside the image); the depth test
  // below against the view's rendering stands for steps 3-4 (a surface facing away or hidden
  // lies behind the rendered one).
  Eigen::Vector3d cam;
  const std::optional<Eigen::Vector2d> pixel = render::ProjectInField(view.geometry, world, &cam);
  if (!pixel) return sample;
  const double z = cam.z();
  const double px = pixel->x(), py = pixel->y();
  const int width = view.depth.width(), height = view.depth.height();
  if (!(px >= 0 && px < width && py >= 0 && py < height)) return sample;
  // The rendered depth at the pixel agrees with the vertex's. Tested before the ray below (both
  // must hold, so the order changes no result): most vertices that fail fail here (hidden),
  // and the ray table is then not read.
  const double tolerance = view.relative_tolerance * z + radius;
  const int ix = std::min(static_cast<int>(px), width - 1);
  const int iy = std::min(static_cast<int>(py), height - 1);
  if (!DepthAgrees(view.depth.at(ix, iy), z, tolerance)) return sample;
  // And the pixel's rendered ray points back at the vertex: the depth read there is this
  // vertex's (the ray table and the projection agree to a pixel).
  float xn = 0, yn = 0;
  if (!view.rays.Ray(static_cast<float>(px), static_cast<float>(py), &xn, &yn)) return sample;
  const double u = cam.x() / z, v = cam.y() / z;
  const double slack = 1.0 + u * u + v * v;  // one pixel, widened off-axis (fisheye)
  if (std::abs(xn - u) * view.fx > slack || std::abs(yn - v) * view.fy > slack) return sample;
  sample.visible = true;

  // Bilinear over the 4 pixel centres around p, qualifying pixels only.
  const double gx = px - 0.5, gy = py - 0.5;
  const int x0 = static_cast<int>(std::floor(gx)), y0 = static_cast<int>(std::floor(gy));
  const double ax = gx - x0, ay = gy - y0;
  double sum = 0, weight_sum = 0;
  for (int j = 0; j < 2; ++j) {
    const int y = y0 + j;
    if (y < 0 || y >= height) continue;
    const double wy = j == 0 ? 1 - ay : ay;
    for (int i = 0; i < 2; ++i) {
      const int x = x0 + i;
      if (x < 0 || x >= width) continue;
      const double w = (i == 0 ? 1 - ax : ax) * wy;
      if (!(w > 0)) continue;
      const float e = view.error.at(x, y);
      if (!std::isfinite(e) || !DepthAgrees(view.depth.at(x, y), z, tolerance)) continue;
      sum += w * e;
      weight_sum += w;
    }
  }
  if (weight_sum > 0) {
    sample.error = sum / weight_sum;
    sample.has_error = true;
  }
  return sample;
}

double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

struct ErrorsFolder {
  std::string prefix;  // "fold_00/" or ""
  fs::path folder;
};

// The errors folders of a run directory (evaluate: per fold, in name order; compare: one).
// Throws when the run directory does not exist or has neither layout (if `required`).
std::vector<ErrorsFolder> ErrorsFolders(const fs::path& run_dir, bool required) {
  std::error_code ec;
  if (!fs::is_directory(run_dir, ec)) {
    if (!required) return {};
    ThrowError("{}: run directory does not exist{}", run_dir.string(),
               fs::exists(run_dir, ec) ? " (not a folder)" : "");
  }
  std::vector<ErrorsFolder> folders;
  if (fs::is_directory(run_dir / "folds", ec)) {
    std::vector<fs::path> folds;
    for (const fs::directory_entry& entry : fs::directory_iterator(run_dir / "folds")) {
      if (entry.is_directory()) folds.push_back(entry.path());
    }
    std::sort(folds.begin(), folds.end());
    for (const fs::path& fold : folds) {
      if (fs::is_directory(fold / "errors", ec)) {
        folders.push_back({fold.filename().string() + "/", fold / "errors"});
      }
    }
    return folders;  // an evaluate run whose folds have no errors yet: nothing found
  }
  if (fs::is_directory(run_dir / "errors", ec)) return {{"", run_dir / "errors"}};
  if (!required) return {};
  ThrowError(
      "{}: not a run directory of rephoto evaluate (folds/*/errors/) or rephoto compare "
      "(errors/)",
      run_dir.string());
}

// Relative paths (generic, without the ".exr") of the .exr files under `folder`.
std::vector<std::string> ExrStems(const fs::path& folder) {
  std::vector<std::string> stems;
  for (const fs::directory_entry& entry : fs::recursive_directory_iterator(folder)) {
    if (!entry.is_regular_file()) continue;
    const fs::path& path = entry.path();
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (ext != ".exr") continue;
    stems.push_back(
        fs::path(path).replace_extension("").lexically_relative(folder).generic_string());
  }
  std::sort(stems.begin(), stems.end());
  return stems;
}

template <typename T>
void Put(std::string& buffer, T value) {
  static_assert(std::endian::native == std::endian::little, "PLY writer assumes little endian");
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  buffer.append(bytes, sizeof(T));
}

}  // namespace

ProjectResult ProjectErrors(const mesh::Mesh& model, const std::vector<ProjectView>& views,
                            const ProjectOptions& options) {
  REPHOTO_CHECK(model.vertex_count() > 0, "project: the model has no vertices");
  CheckOptions(options);
  CheckViews(views, options);  // before the BVH is built: bad input fails fast
  mesh::Mesh geometry;         // what the depth maps need
  geometry.positions = model.positions;
  geometry.faces = model.faces;
  if (model.is_point_cloud()) {
    geometry.normals = model.normals;  // disc orientation
    geometry.radii = model.radii;
  }
  render::ModelOptions model_options = options.model_options;
  model_options.load_textures = false;
  const render::RenderModel render_model(std::move(geometry), model_options, "model");
  return ProjectErrors(render_model, views, options);
}

ProjectResult ProjectErrors(const render::RenderModel& model, const std::vector<ProjectView>& views,
                            const ProjectOptions& options) {
  const mesh::Mesh& mesh = model.mesh();
  const size_t n = mesh.vertex_count();
  REPHOTO_CHECK(n > 0, "project: the model has no vertices");
  CheckOptions(options);
  CheckViews(views, options);
  const bool points = model.representation() == render::Representation::kPointCloud;
  const std::vector<float>& radii = model.point_radii();

  std::vector<double> sums(n, 0.0);
  ProjectResult result;
  // Per face (meshes): the mean over views of each view's mean over the face's interior
  // sample points (see project.h).
  const size_t face_count = points || !options.face_errors ? 0 : mesh.faces.size();
  std::vector<double> face_sums(face_count, 0.0);
  std::vector<uint32_t> face_views(face_count, 0);
  std::vector<float> longest_edge(face_count, 0.f);
  for (size_t f = 0; f < face_count; ++f) {
    const mesh::Triangle& t = mesh.faces[f];
    const Eigen::Vector3f &a = mesh.positions[t[0]], &b = mesh.positions[t[1]],
                          &c = mesh.positions[t[2]];
    longest_edge[f] = std::max({(a - b).norm(), (b - c).norm(), (c - a).norm()});
  }
  // This view's sample of each vertex (NaN = none), for the faces smaller than 4 pixels.
  std::vector<float> vertex_sample(face_count > 0 ? n : 0, kNaN);
  result.view_count.assign(n, 0);
  result.view_seen_vertices.assign(views.size(), 0);
  std::vector<uint8_t> visible(n, 0);

  render::RenderOptions render_options;
  render_options.samples_per_pixel = 1;
  render_options.pattern = render::SamplePattern::kRegular;
  render_options.backfaces = options.backfaces;
  render::Rephoto rephoto;
  Image error;
  std::unique_ptr<Progress> progress;
  if (options.show_progress) progress = std::make_unique<Progress>("project", views.size());

  for (size_t v = 0; v < views.size(); ++v) {
    const ProjectView& view = views[v];
    auto start = std::chrono::steady_clock::now();
    io::ReadImage(view.error_image, &error);
    const camera::Camera camera =
        CameraForImage(view, error.width(), error.height(), error.channels(), options);
    result.project_seconds += Seconds(start);

    start = std::chrono::steady_clock::now();
    const std::shared_ptr<const render::CameraRays> rays = model.RaysFor(camera);
    if (view.depth_image.empty()) {
      render::RenderRephoto(model, *rays, view.cam_from_world, render_options, &rephoto);
    } else {
      io::ReadImage(view.depth_image, &rephoto.depth);  // its size was checked by CheckViews
    }
    result.render_seconds += Seconds(start);

    start = std::chrono::steady_clock::now();
    const render::ViewGeometry geometry(camera, view.cam_from_world);
    const ViewContext context{
        geometry,
        *rays,
        rephoto.depth,
        error,
        options.depth_tolerance + options.footprint_tolerance / camera.MeanFocalLength(),
        camera.FocalLengthX(),
        camera.FocalLengthY()};
    result.view_seen_vertices[v] =
        ParallelSum<size_t>(0, static_cast<int64_t>(n), 4096, [&](int64_t begin, int64_t end) {
          size_t seen = 0;
          for (int64_t i = begin; i < end; ++i) {
            const double radius = points && !radii.empty() ? radii[i] : 0.0;
            const Sample s = SampleVertex(context, mesh.positions[i].cast<double>(), radius);
            if (!vertex_sample.empty()) {
              vertex_sample[i] = s.visible && s.has_error ? static_cast<float>(s.error) : kNaN;
            }
            if (!s.visible) continue;
            visible[i] = 1;
            if (!s.has_error) continue;
            sums[i] += s.error;
            ++result.view_count[i];
            ++seen;
          }
          return seen;
        });
    const double focal = std::max(camera.FocalLengthX(), camera.FocalLengthY());
    ParallelFor(0, static_cast<int64_t>(face_count), 4096, [&](int64_t begin, int64_t end) {
      for (int64_t f = begin; f < end; ++f) {
        const mesh::Triangle& face = mesh.faces[f];
        const Eigen::Vector3d a = mesh.positions[face[0]].cast<double>();
        const Eigen::Vector3d b = mesh.positions[face[1]].cast<double>();
        const Eigen::Vector3d c = mesh.positions[face[2]].cast<double>();
        double sum = 0;
        int count = 0;
        const double z = view.cam_from_world.CamFromWorld((a + b + c) / 3).z();
        if (!(z > 0)) continue;
        if (longest_edge[f] * focal / z < 4.0) {
          // Smaller than 4 pixels: its corners' samples of this view describe it.
          for (uint32_t index : face) {
            if (std::isfinite(vertex_sample[index])) {
              sum += vertex_sample[index];
              ++count;
            }
          }
        } else {
          for (const auto& w : kFaceSamples) {
            const Sample sample = SampleVertex(context, w[0] * a + w[1] * b + w[2] * c, 0.0);
            if (sample.has_error) {
              sum += sample.error;
              ++count;
            }
          }
        }
        if (count > 0) {
          face_sums[f] += sum / count;
          ++face_views[f];
        }
      }
    });
    result.project_seconds += Seconds(start);
    if (progress) progress->Advance(ViewLabel(view));
  }
  if (progress) progress->Finish();

  result.face_error.assign(face_count, kNaN);
  for (size_t f = 0; f < face_count; ++f) {
    if (face_views[f] > 0) result.face_error[f] = static_cast<float>(face_sums[f] / face_views[f]);
  }
  result.vertex_error.assign(n, kNaN);
  std::vector<double> finite;
  finite.reserve(n);
  for (size_t i = 0; i < n; ++i) {
    result.visible_vertices += visible[i];
    if (result.view_count[i] == 0) continue;
    const double mean = sums[i] / result.view_count[i];
    result.vertex_error[i] = static_cast<float>(mean);
    finite.push_back(result.vertex_error[i]);
  }
  result.seen_vertices = finite.size();
  if (options.fixed_range) {
    result.low = options.fixed_range->first;
    result.high = options.fixed_range->second;
  } else if (finite.empty()) {
    result.low = result.high = kNaN;
  } else {
    result.low = static_cast<float>(Quantile(finite, options.low_percentile / 100.0));
    result.high = static_cast<float>(Quantile(finite, options.high_percentile / 100.0));
    if (options.higher_is_better) std::swap(result.low, result.high);
  }
  return result;
}

std::array<uint8_t, 3> ErrorColour(float error, float low, float high) {
  if (!std::isfinite(error)) return {128, 128, 128};
  // With low > high the same formula runs the map backwards (a reversed range).
  const float t = high != low ? (error - low) / (high - low) : 0.0f;
  const std::array<float, 3> c = JetColor(std::clamp(t, 0.0f, 1.0f));
  return {static_cast<uint8_t>(std::lround(255.0f * c[0])),
          static_cast<uint8_t>(std::lround(255.0f * c[1])),
          static_cast<uint8_t>(std::lround(255.0f * c[2]))};
}

void WriteProjectedPly(const mesh::Mesh& model, const ProjectResult& result,
                       const std::filesystem::path& out) {
  const size_t n = model.vertex_count();
  REPHOTO_CHECK(result.vertex_error.size() == n && result.view_count.size() == n,
                "{}: the projection has {} vertices but the model has {}", out.string(),
                result.vertex_error.size(), n);
  const bool normals = model.normals.size() == n && n > 0;
  const bool face_errors = !model.faces.empty() && result.face_error.size() == model.faces.size();
  std::string header = "ply\nformat binary_little_endian 1.0\n";
  header += "comment rephoto project: per-vertex mean of the projected error images\n";
  if (face_errors) {
    header += "comment per face: mean over the views of the error at 4 points inside the face\n";
  }
  header += fmt::format("comment colour range (jet) low {} high {}; grey = not seen\n", result.low,
                        result.high);
  header += fmt::format("comment seen vertices {} of {}\n", result.seen_vertices, n);
  header += fmt::format("element vertex {}\n", n);
  header += "property float x\nproperty float y\nproperty float z\n";
  if (normals) header += "property float nx\nproperty float ny\nproperty float nz\n";
  header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  header += "property float error\nproperty float quality\nproperty uint views\n";
  if (!model.faces.empty()) {
    header += fmt::format("element face {}\n", model.faces.size());
    header += "property list uchar int vertex_indices\n";
    if (face_errors) {
      header += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
      header += "property float error\nproperty float quality\n";
    }
  }
  header += "end_header\n";

  WriteFileAtomically(out, [&](const fs::path& temporary) {
    std::ofstream file(temporary, std::ios::binary);
    REPHOTO_CHECK(file.good(), "{}: cannot open for writing", out.string());
    file.write(header.data(), static_cast<std::streamsize>(header.size()));
    std::string buffer;
    constexpr size_t kFlush = 1 << 20;
    buffer.reserve(kFlush + 64);
    auto flush = [&](bool force) {
      if (buffer.size() >= kFlush || (force && !buffer.empty())) {
        file.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
        buffer.clear();
      }
    };
    for (size_t i = 0; i < n; ++i) {
      const Eigen::Vector3f& p = model.positions[i];
      Put(buffer, p.x());
      Put(buffer, p.y());
      Put(buffer, p.z());
      if (normals) {
        Put(buffer, model.normals[i].x());
        Put(buffer, model.normals[i].y());
        Put(buffer, model.normals[i].z());
      }
      const std::array<uint8_t, 3> rgb =
          ErrorColour(result.vertex_error[i], result.low, result.high);
      buffer.append(reinterpret_cast<const char*>(rgb.data()), 3);
      Put(buffer, result.vertex_error[i]);
      Put(buffer, result.vertex_error[i]);  // quality: MeshLab's per-vertex scalar
      Put(buffer, result.view_count[i]);
      flush(false);
    }
    for (size_t f = 0; f < model.faces.size(); ++f) {
      Put(buffer, static_cast<uint8_t>(3));
      for (uint32_t index : model.faces[f]) Put(buffer, static_cast<int32_t>(index));
      if (face_errors) {
        const std::array<uint8_t, 3> rgb =
            ErrorColour(result.face_error[f], result.low, result.high);
        buffer.append(reinterpret_cast<const char*>(rgb.data()), 3);
        Put(buffer, result.face_error[f]);
        Put(buffer, result.face_error[f]);
      }
      flush(false);
    }
    flush(true);
    file.flush();
    REPHOTO_CHECK(file.good(), "{}: write failed", out.string());
  });
}

std::vector<ProjectView> FindErrorImages(const scene::Scene& scene,
                                         const std::filesystem::path& run_dir,
                                         std::string_view metric, size_t* views_without_errors,
                                         size_t* unmatched_images) {
  REPHOTO_CHECK(!metric.empty() && metric.find('/') == std::string_view::npos &&
                    metric.find('.') == std::string_view::npos,
                "{}: invalid metric name '{}'", run_dir.string(), metric);
  const std::vector<ErrorsFolder> folders = ErrorsFolders(run_dir, /*required=*/true);
  const std::string suffix = fmt::format(".{}.exr", metric);
  const std::vector<std::string> stems = scene::OutputStems(scene);
  const std::set<std::string> known(stems.begin(), stems.end());
  std::vector<ProjectView> views;
  std::vector<uint8_t> found(scene.views.size(), 0);
  size_t unmatched = 0;
  std::error_code ec;
  for (const ErrorsFolder& folder : folders) {
    for (size_t v = 0; v < scene.views.size(); ++v) {
      const fs::path path = folder.folder / (stems[v] + suffix);
      if (!fs::is_regular_file(path, ec)) continue;
      const scene::View& view = scene.views[v];
      views.push_back({scene.CameraOf(view), view.cam_from_world, path, folder.prefix + stems[v]});
      found[v] = 1;
    }
    const std::string metric_ext = fmt::format(".{}", metric);
    for (const std::string& stem : ExrStems(folder.folder)) {
      if (stem.size() <= metric_ext.size() ||
          stem.compare(stem.size() - metric_ext.size(), metric_ext.size(), metric_ext) != 0) {
        continue;
      }
      unmatched += !known.contains(stem.substr(0, stem.size() - metric_ext.size()));
    }
  }
  if (views_without_errors != nullptr) {
    *views_without_errors = static_cast<size_t>(std::count(found.begin(), found.end(), 0));
  }
  if (unmatched_images != nullptr) *unmatched_images = unmatched;
  return views;
}

std::vector<std::string> ListErrorMetrics(const std::filesystem::path& run_dir) {
  std::set<std::string> metrics;
  for (const ErrorsFolder& folder : ErrorsFolders(run_dir, /*required=*/false)) {
    for (const std::string& stem : ExrStems(folder.folder)) {
      const size_t slash = stem.rfind('/');
      const size_t dot = stem.rfind('.');
      if (dot == std::string::npos || dot + 1 == stem.size() ||
          (slash != std::string::npos && dot < slash) ||
          dot == (slash == std::string::npos ? 0 : slash + 1)) {
        continue;
      }
      metrics.insert(stem.substr(dot + 1));
    }
  }
  return {metrics.begin(), metrics.end()};
}

std::vector<float> ProjectErrorsOntoGaussians(const splat::GaussianModel& model,
                                              const std::vector<ProjectView>& views,
                                              const splat::GaussianRenderOptions& options,
                                              const ProjectOptions& project_options, size_t* seen) {
  splat::GaussianErrorAccumulator accumulator;
  accumulator.Reset(model.size());
  Image error;
  for (const ProjectView& view : views) {
    io::ReadImage(view.error_image, &error);
    const camera::Camera camera =
        CameraForImage(view, error.width(), error.height(), error.channels(), project_options);
    splat::AccumulateGaussianErrors(model, camera, view.cam_from_world, options, error,
                                    &accumulator);
  }
  std::vector<float> mean(model.size(), std::numeric_limits<float>::quiet_NaN());
  size_t count = 0;
  for (size_t g = 0; g < mean.size(); ++g) {
    if (accumulator.weight[g] > 0) {
      mean[g] = static_cast<float>(accumulator.weighted_error[g] / accumulator.weight[g]);
      ++count;
    }
  }
  if (seen != nullptr) *seen = count;
  return mean;
}

}  // namespace rephoto::project
