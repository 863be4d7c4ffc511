// Renderer speed: BVH build, 1 and 4 samples per pixel, 1920x1080, a procedural
// 1,000,000-triangle vertex-coloured mesh (displaced UV sphere filling most of the frame), and
// the same mesh and camera rasterized with OpenGL on Mesa llvmpipe through EGL surfaceless
// (the paper's rephotographer renders with OpenGL), when the benchmark was built with EGL.
//
// Run: build-*/bench/rephoto_bench_render --benchmark_repetitions=5
//        --benchmark_report_aggregates_only=true
// Threads: all cores (TBB default); pass --threads=N through REPHOTO_BENCH_THREADS=N.
// Renderer vs Embree: BM_EmbreeFloor/8 and /16 (rtcIntersect8/16 alone on the same BVH and
// rays) next to BM_Render; BM_RenderOverFloor/spp renders and traces both floors in turns and
// reports the ratio of the medians (robust when other programs load the machine):
//   rephoto_bench_render --benchmark_filter=BM_RenderOverFloor
// BM_RenderFile renders a mesh of your own at a scene's view, as `rephoto evaluate` does (when
// REPHOTO_BENCH_MESH=model.ply and REPHOTO_BENCH_SCENE=scene are set; REPHOTO_BENCH_VIEW=N picks
// the view, default 0, and REPHOTO_BENCH_SHORT_SIDE=S the evaluation resolution, default 768),
// e.g. a reconstruction from examples/pipelines of ../shared/data/strecha_fountain_p11.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <memory>
#include <vector>

#include "bench_cpu.h"
#include "rephoto/core/parallel.h"
#include "rephoto/core/process.h"
#include "rephoto/mesh/mesh.h"
#include "rephoto/mesh/read_mesh.h"
#include "rephoto/render/colorize.h"
#include "rephoto/render/render.h"
#include "rephoto/scene/read_scene.h"

#ifdef REPHOTO_BENCH_EGL
#define EGL_EGLEXT_PROTOTYPES
#define GL_GLEXT_PROTOTYPES
#include <EGL/egl.h>
#include <EGL/eglext.h>
#include <GL/gl.h>
#include <GL/glext.h>
#endif

namespace {

using rephoto::bench::BenchPose;

using rephoto::camera::Camera;
using rephoto::camera::CameraModel;
using rephoto::camera::Pose;
using rephoto::mesh::Mesh;

constexpr int kWidth = 1920;
constexpr int kHeight = 1080;

// A UV sphere of 500 x 1000 quads (1,000,000 triangles) with a smooth bumpy displacement and
// colours varying along it.
const Mesh& BenchMesh() {
  static const Mesh mesh = [] {
    Mesh m;
    const int rows = 500, cols = 1000;
    const double pi = 3.14159265358979323846;
    for (int i = 0; i <= rows; ++i) {
      const double theta = pi * i / rows;
      for (int j = 0; j < cols; ++j) {
        const double phi = 2 * pi * j / cols;
        const double bump = 1.0 + 0.03 * std::sin(17 * theta) * std::cos(23 * phi) +
                            0.01 * std::sin(71 * theta + 3 * phi);
        m.positions.emplace_back(bump * std::sin(theta) * std::cos(phi),
                                 bump * std::sin(theta) * std::sin(phi), bump * std::cos(theta));
        m.colors.emplace_back(0.5 + 0.5 * std::sin(9 * phi), 0.5 + 0.5 * std::cos(7 * theta),
                              0.5 + 0.5 * std::sin(40 * theta + 31 * phi));
      }
    }
    for (int i = 0; i < rows; ++i) {
      for (int j = 0; j < cols; ++j) {
        const uint32_t a = i * cols + j, b = i * cols + (j + 1) % cols;
        const uint32_t c = (i + 1) * cols + j, d = (i + 1) * cols + (j + 1) % cols;
        m.faces.push_back({a, c, b});
        m.faces.push_back({b, c, d});
      }
    }
    return m;
  }();
  return mesh;
}

Camera BenchCamera() {
  Camera camera;
  camera.model = CameraModel::kPinhole;
  camera.width = kWidth;
  camera.height = kHeight;
  camera.params = {1400.0, 1400.0, kWidth / 2.0, kHeight / 2.0};
  return camera;
}

const rephoto::render::RenderModel& BenchModel() {
  static const auto model = std::make_unique<rephoto::render::RenderModel>(BenchMesh());
  return *model;
}

double Coverage(const rephoto::Image& rgba) {
  double sum = 0;
  for (size_t i = 0; i < rgba.pixel_count(); ++i) sum += rgba.data()[4 * i + 3];
  return sum / static_cast<double>(rgba.pixel_count());
}

// Building the BVH (and the rest of a RenderModel) of `mesh`.
void BuildBvh(benchmark::State& state, const Mesh& mesh) {
  double build = 0;
  {
    rephoto::bench::CpuCounter cpu(state);
    for (auto _ : state) {
      rephoto::render::RenderModel model(mesh);
      build = model.build_seconds();
      benchmark::DoNotOptimize(model.scene());
    }
  }
  state.counters["triangles"] = static_cast<double>(mesh.faces.size());
  state.counters["commit_ms"] = build * 1e3;  // rtcCommitScene only (rest: buffer copies)
}

// Rendering `model` at `camera` and `pose` with state.range(0) samples per pixel and packets of
// `packet_width` rays (0: by CPU).
void Render(benchmark::State& state, const rephoto::render::RenderModel& model,
            const Camera& camera, const Pose& pose, int packet_width = 0) {
  const auto rays = model.RaysFor(camera);
  rephoto::render::RenderOptions options;
  options.samples_per_pixel = static_cast<int>(state.range(0));
  options.packet_width = packet_width;
  rephoto::render::Rephoto out;
  rephoto::render::RenderRephoto(model, *rays, pose, options, &out);  // warm buffers
  {
    rephoto::bench::CpuCounter cpu(state, "cpu_ms_per_frame");
    for (auto _ : state) {
      rephoto::render::RenderRephoto(model, *rays, pose, options, &out);
      benchmark::DoNotOptimize(out.color.data());
    }
  }
  state.counters["coverage"] = Coverage(out.color);
  state.counters["triangles"] = static_cast<double>(model.mesh().faces.size());
  state.counters["Mrays/s"] =
      benchmark::Counter(static_cast<double>(camera.width) * camera.height *
                             options.samples_per_pixel * state.iterations() / 1e6,
                         benchmark::Counter::kIsRate);
}

void BM_BuildBvh(benchmark::State& state) { BuildBvh(state, BenchMesh()); }
BENCHMARK(BM_BuildBvh)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();

void BM_Render(benchmark::State& state) { Render(state, BenchModel(), BenchCamera(), BenchPose()); }
BENCHMARK(BM_Render)->Arg(1)->Arg(4)->Unit(benchmark::kMillisecond)->UseRealTime();
// The same with the packet width forced: samples per pixel, rays per packet (8 or 16).
void BM_RenderPacket(benchmark::State& state) {
  Render(state, BenchModel(), BenchCamera(), BenchPose(), static_cast<int>(state.range(1)));
}
BENCHMARK(BM_RenderPacket)
    ->Args({1, 8})
    ->Args({1, 16})
    ->Args({4, 8})
    ->Args({4, 16})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// The Embree floor of primary visibility: the same BVH (BenchModel's scene), camera and pose
// as BM_Render at 1 sample per pixel (rays through the same sample positions), but only
// rtcIntersect8 (4 x 2 pixel tiles) or rtcIntersect16 (4 x 4 tiles): the ray directions are
// made once outside the timed frames, no backface filter, no shading, only the depth written.
// BM_Render/1 over this is rephoto's overhead on top of Embree.
class EmbreeFloor {
 public:
  explicit EmbreeFloor(int lanes) : lanes_(lanes) {
    const auto& model = BenchModel();
    const Camera camera = BenchCamera();
    const Pose pose = BenchPose();
    const auto rays = model.RaysFor(camera);
    const Eigen::Matrix3f world_from_cam = pose.rotation.transpose().cast<float>();
    origin_ = pose.Center().cast<float>();
    width_ = camera.width;
    height_ = camera.height;
    const rephoto::render::RenderOptions options;  // 1 sample per pixel, as BM_Render/1
    dirs_.resize(3 * static_cast<size_t>(width_) * height_);
    has_ray_.resize(static_cast<size_t>(width_) * height_);
    for (int y = 0; y < height_; ++y) {
      for (int x = 0; x < width_; ++x) {
        const Eigen::Vector2f offset = rephoto::render::SampleOffset(x, y, 0, options);
        float xn, yn;
        const size_t i = static_cast<size_t>(y) * width_ + x;
        has_ray_[i] = rays->Ray(x + offset.x(), y + offset.y(), &xn, &yn);
        const Eigen::Vector3f d =
            world_from_cam.col(0) * xn + world_from_cam.col(1) * yn + world_from_cam.col(2);
        for (int c = 0; c < 3; ++c) dirs_[3 * i + c] = d[c];
      }
    }
    depth_.resize(static_cast<size_t>(width_) * height_);
    Frame();  // warm
  }

  void Frame() {
    const int tile_h = lanes_ / 4;
    const int tile_rows = (height_ + tile_h - 1) / tile_h;
    RTCScene scene = BenchModel().scene();
    rephoto::ParallelFor(0, tile_rows, 1, [&](int64_t row_begin, int64_t row_end) {
      RTCIntersectContext context;
      rtcInitIntersectContext(&context);
      context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
      alignas(64) RTCRayHit16 packet16;
      alignas(64) RTCRayHit8 packet8;
      alignas(64) int valid[16];
      for (int64_t tile_row = row_begin; tile_row < row_end; ++tile_row) {
        const int y0 = static_cast<int>(tile_row) * tile_h;
        for (int x0 = 0; x0 < width_; x0 += 4) {
          auto fill = [&](auto& packet) {
            for (int k = 0; k < lanes_; ++k) {
              const int px = x0 + (k & 3), py = y0 + (k >> 2);
              const size_t i = static_cast<size_t>(py) * width_ + px;
              valid[k] = px < width_ && py < height_ && has_ray_[i] ? -1 : 0;
              packet.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
              if (!valid[k]) continue;
              packet.ray.org_x[k] = origin_.x();
              packet.ray.org_y[k] = origin_.y();
              packet.ray.org_z[k] = origin_.z();
              packet.ray.dir_x[k] = dirs_[3 * i];
              packet.ray.dir_y[k] = dirs_[3 * i + 1];
              packet.ray.dir_z[k] = dirs_[3 * i + 2];
              packet.ray.tnear[k] = 0.0f;
              packet.ray.tfar[k] = std::numeric_limits<float>::infinity();
              packet.ray.time[k] = 0.0f;
              packet.ray.mask[k] = 0xFFFFFFFFu;
              packet.ray.id[k] = static_cast<unsigned>(k);
              packet.ray.flags[k] = 0;
            }
          };
          auto store = [&](const auto& packet) {
            for (int k = 0; k < lanes_; ++k) {
              if (!valid[k]) continue;
              const int px = x0 + (k & 3), py = y0 + (k >> 2);
              depth_[static_cast<size_t>(py) * width_ + px] =
                  packet.hit.geomID[k] == RTC_INVALID_GEOMETRY_ID ? 0.0f : packet.ray.tfar[k];
            }
          };
          if (lanes_ == 16) {
            fill(packet16);
            rtcIntersect16(valid, scene, &context, &packet16);
            store(packet16);
          } else {
            fill(packet8);
            rtcIntersect8(valid, scene, &context, &packet8);
            store(packet8);
          }
        }
      }
    });
  }
  const float* depth() const { return depth_.data(); }
  int64_t rays() const { return static_cast<int64_t>(width_) * height_; }

 private:
  int lanes_, width_ = 0, height_ = 0;
  Eigen::Vector3f origin_;
  std::vector<float> dirs_;
  std::vector<uint8_t> has_ray_;
  std::vector<float> depth_;
};

// Arg: the packet width.
void BM_EmbreeFloor(benchmark::State& state) {
  EmbreeFloor floor(static_cast<int>(state.range(0)));
  {
    rephoto::bench::CpuCounter cpu(state, "cpu_ms_per_frame");
    for (auto _ : state) {
      floor.Frame();
      benchmark::DoNotOptimize(floor.depth());
    }
  }
  state.counters["Mrays/s"] = benchmark::Counter(
      static_cast<double>(floor.rays() * state.iterations()) / 1e6, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_EmbreeFloor)->Arg(8)->Arg(16)->Unit(benchmark::kMillisecond)->UseRealTime();

double Median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  return values[values.size() / 2];
}

// rephoto (packet width by CPU, state.range(0) samples per pixel) and both Embree floors in
// turns within each iteration, so that the load other programs put on the machine meets all
// three alike. Counters: medians over the iterations of the process CPU milliseconds (all
// threads) and wall milliseconds per frame, and the ratio of rephoto's CPU time per ray to the
// faster floor's (`over_floor`; `over_floor_wall` the same for wall time).
void BM_RenderOverFloor(benchmark::State& state) {
  static EmbreeFloor floor8(8), floor16(16);
  const auto& model = BenchModel();
  const Camera camera = BenchCamera();
  const auto rays = model.RaysFor(camera);
  rephoto::render::RenderOptions options;
  options.samples_per_pixel = static_cast<int>(state.range(0));
  rephoto::render::Rephoto out;
  rephoto::render::RenderRephoto(model, *rays, BenchPose(), options, &out);  // warm buffers
  std::vector<double> cpu[3], wall[3];
  auto timed = [&](int which, auto&& frame) {
    const double cpu_start = rephoto::ProcessCpuSeconds();
    const auto wall_start = std::chrono::steady_clock::now();
    frame();
    wall[which].push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count() * 1e3);
    cpu[which].push_back((rephoto::ProcessCpuSeconds() - cpu_start) * 1e3);
  };
  for (auto _ : state) {
    timed(0, [&] { rephoto::render::RenderRephoto(model, *rays, BenchPose(), options, &out); });
    timed(1, [&] { floor8.Frame(); });
    timed(2, [&] { floor16.Frame(); });
  }
  const double spp = options.samples_per_pixel;
  const double render_cpu = Median(cpu[0]), render_wall = Median(wall[0]);
  const double floor_cpu = std::min(Median(cpu[1]), Median(cpu[2]));
  const double floor_wall = std::min(Median(wall[1]), Median(wall[2]));
  state.counters["render_cpu_ms"] = render_cpu;
  state.counters["floor8_cpu_ms"] = Median(cpu[1]);
  state.counters["floor16_cpu_ms"] = Median(cpu[2]);
  state.counters["render_wall_ms"] = render_wall;
  state.counters["floor8_wall_ms"] = Median(wall[1]);
  state.counters["floor16_wall_ms"] = Median(wall[2]);
  state.counters["over_floor"] = render_cpu / (spp * floor_cpu);
  state.counters["over_floor_wall"] = render_wall / (spp * floor_wall);
}
BENCHMARK(BM_RenderOverFloor)->Arg(1)->Arg(4)->Unit(benchmark::kMillisecond)->Iterations(15);

// Your own model and scene: REPHOTO_BENCH_MESH and REPHOTO_BENCH_SCENE (read once). False, with
// the benchmark skipped, unless they are set (the scene only when `scene` is asked for).
bool FileInputs(benchmark::State& state, const Mesh** mesh,
                const rephoto::scene::Scene** scene = nullptr) {
  static const std::unique_ptr<Mesh> file_mesh = []() {
    const char* path = std::getenv("REPHOTO_BENCH_MESH");
    return path == nullptr ? nullptr : std::make_unique<Mesh>(rephoto::mesh::ReadMesh(path));
  }();
  static const std::unique_ptr<rephoto::scene::Scene> file_scene = []() {
    const char* path = std::getenv("REPHOTO_BENCH_SCENE");
    return path == nullptr
               ? nullptr
               : std::make_unique<rephoto::scene::Scene>(rephoto::scene::ReadScene(path));
  }();
  *mesh = file_mesh.get();
  if (scene != nullptr) *scene = file_scene.get();
  if (*mesh == nullptr || (scene != nullptr && *scene == nullptr)) {
    state.SkipWithError(scene != nullptr ? "set REPHOTO_BENCH_MESH and REPHOTO_BENCH_SCENE"
                                         : "set REPHOTO_BENCH_MESH");
    return false;
  }
  return true;
}

void BM_BuildBvhFile(benchmark::State& state) {
  const Mesh* mesh = nullptr;
  if (FileInputs(state, &mesh)) BuildBvh(state, *mesh);
}
BENCHMARK(BM_BuildBvhFile)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();

// Colouring REPHOTO_BENCH_MESH from the first 3 (REPHOTO_BENCH_VIEWS) photos of
// REPHOTO_BENCH_SCENE on its BVH (as `rephoto evaluate --colorize` does per fold; photo decoding
// included).
void BM_ColorizeFile(benchmark::State& state) {
  const Mesh* mesh = nullptr;
  const rephoto::scene::Scene* scene = nullptr;
  if (!FileInputs(state, &mesh, &scene)) return;
  const rephoto::render::RenderModel model(*mesh);
  std::vector<size_t> views;
  const char* count_env = std::getenv("REPHOTO_BENCH_VIEWS");
  const size_t count = count_env != nullptr ? std::strtoul(count_env, nullptr, 10) : 3;
  for (size_t v = 0; v < std::min(count, scene->views.size()); ++v) views.push_back(v);
  {
    rephoto::bench::CpuCounter cpu(state);
    for (auto _ : state) {
      auto colors = rephoto::render::ColorizeVertices(model, *scene, views);
      benchmark::DoNotOptimize(colors.colors.data());
    }
  }
  state.counters["vertices"] = static_cast<double>(mesh->positions.size());
}
BENCHMARK(BM_ColorizeFile)->Unit(benchmark::kMillisecond)->Iterations(3)->UseRealTime();

// Rendering REPHOTO_BENCH_MESH at view REPHOTO_BENCH_VIEW (default 0) of REPHOTO_BENCH_SCENE,
// scaled to the shorter side REPHOTO_BENCH_SHORT_SIDE (default 768), as evaluate renders.
void BM_RenderFile(benchmark::State& state) {
  const Mesh* mesh = nullptr;
  const rephoto::scene::Scene* scene = nullptr;
  if (!FileInputs(state, &mesh, &scene)) return;
  static const auto model = std::make_unique<rephoto::render::RenderModel>(*mesh);
  const char* view_env = std::getenv("REPHOTO_BENCH_VIEW");
  const char* side_env = std::getenv("REPHOTO_BENCH_SHORT_SIDE");
  const size_t view = view_env != nullptr ? std::strtoul(view_env, nullptr, 10) : 0;
  const int side = side_env != nullptr ? std::atoi(side_env) : 768;
  if (view >= scene->views.size() || side <= 0) {
    state.SkipWithError("REPHOTO_BENCH_VIEW or REPHOTO_BENCH_SHORT_SIDE out of range");
    return;
  }
  Camera camera = scene->CameraOf(scene->views[view]);
  const double scale = static_cast<double>(side) / std::min(camera.width, camera.height);
  camera = camera.Scaled(static_cast<int>(std::lround(camera.width * scale)),
                         static_cast<int>(std::lround(camera.height * scale)));
  Render(state, *model, camera, scene->views[view].cam_from_world);
}
BENCHMARK(BM_RenderFile)->Arg(1)->Arg(4)->Unit(benchmark::kMillisecond)->UseRealTime();

#ifdef REPHOTO_BENCH_EGL
const char* kVertexShader = R"(#version 330 core
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 color;
uniform mat4 clip_from_world;
out vec3 vertex_color;
void main() {
  gl_Position = clip_from_world * vec4(position, 1.0);
  vertex_color = color;
})";
const char* kFragmentShader = R"(#version 330 core
in vec3 vertex_color;
out vec4 frag_color;
void main() { frag_color = vec4(vertex_color, 1.0); })";

// Headless OpenGL 3.3 core context on EGL's surfaceless platform (Mesa llvmpipe), rendering
// into a framebuffer object with `samples` MSAA samples (0 = none).
class GlRenderer {
 public:
  bool Init(int samples, std::string* error) {
    auto get_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
        eglGetProcAddress("eglGetPlatformDisplayEXT"));
    if (get_display == nullptr) return Fail(error, "no eglGetPlatformDisplayEXT");
    display_ = get_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    if (display_ == EGL_NO_DISPLAY || !eglInitialize(display_, nullptr, nullptr)) {
      return Fail(error, "eglInitialize failed");
    }
    const EGLint config_attributes[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE,
                                        EGL_OPENGL_BIT, EGL_NONE};
    EGLConfig config;
    EGLint count = 0;
    if (!eglChooseConfig(display_, config_attributes, &config, 1, &count) || count == 0) {
      return Fail(error, "no EGL config");
    }
    eglBindAPI(EGL_OPENGL_API);
    const EGLint context_attributes[] = {EGL_CONTEXT_MAJOR_VERSION,
                                         3,
                                         EGL_CONTEXT_MINOR_VERSION,
                                         3,
                                         EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                         EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                         EGL_NONE};
    context_ = eglCreateContext(display_, config, EGL_NO_CONTEXT, context_attributes);
    if (context_ == EGL_NO_CONTEXT) return Fail(error, "eglCreateContext failed");
    if (!eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, context_)) {
      return Fail(error, "eglMakeCurrent (surfaceless) failed");
    }
    renderer_name_ = reinterpret_cast<const char*>(glGetString(GL_RENDERER));

    glGenFramebuffers(1, &framebuffer_);
    glBindFramebuffer(GL_FRAMEBUFFER, framebuffer_);
    glGenRenderbuffers(2, renderbuffers_);
    glBindRenderbuffer(GL_RENDERBUFFER, renderbuffers_[0]);
    glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples, GL_RGBA8, kWidth, kHeight);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER,
                              renderbuffers_[0]);
    glBindRenderbuffer(GL_RENDERBUFFER, renderbuffers_[1]);
    glRenderbufferStorageMultisample(GL_RENDERBUFFER, samples, GL_DEPTH_COMPONENT24, kWidth,
                                     kHeight);
    glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER,
                              renderbuffers_[1]);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) {
      return Fail(error, "framebuffer incomplete");
    }
    samples_ = samples;
    if (samples > 0) {  // resolve target for reading back
      glGenFramebuffers(1, &resolve_framebuffer_);
      glBindFramebuffer(GL_FRAMEBUFFER, resolve_framebuffer_);
      glGenRenderbuffers(1, &resolve_renderbuffer_);
      glBindRenderbuffer(GL_RENDERBUFFER, resolve_renderbuffer_);
      glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, kWidth, kHeight);
      glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER,
                                resolve_renderbuffer_);
      glBindFramebuffer(GL_FRAMEBUFFER, framebuffer_);
    }

    program_ = glCreateProgram();
    for (auto [type, source] : {std::pair{GL_VERTEX_SHADER, kVertexShader},
                                std::pair{GL_FRAGMENT_SHADER, kFragmentShader}}) {
      const GLuint shader = glCreateShader(type);
      glShaderSource(shader, 1, &source, nullptr);
      glCompileShader(shader);
      GLint ok = 0;
      glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
      if (!ok) return Fail(error, "shader compilation failed");
      glAttachShader(program_, shader);
    }
    glLinkProgram(program_);
    glUseProgram(program_);

    const Mesh& mesh = BenchMesh();
    std::vector<float> vertices;
    vertices.reserve(mesh.positions.size() * 6);
    for (size_t i = 0; i < mesh.positions.size(); ++i) {
      for (int k = 0; k < 3; ++k) vertices.push_back(mesh.positions[i][k]);
      for (int k = 0; k < 3; ++k) vertices.push_back(mesh.colors[i][k]);
    }
    glGenVertexArrays(1, &vertex_array_);
    glBindVertexArray(vertex_array_);
    GLuint buffers[2];
    glGenBuffers(2, buffers);
    glBindBuffer(GL_ARRAY_BUFFER, buffers[0]);
    glBufferData(GL_ARRAY_BUFFER, vertices.size() * sizeof(float), vertices.data(), GL_STATIC_DRAW);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), nullptr);
    glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float),
                          reinterpret_cast<void*>(3 * sizeof(float)));
    glEnableVertexAttribArray(0);
    glEnableVertexAttribArray(1);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, buffers[1]);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, mesh.faces.size() * 3 * sizeof(uint32_t),
                 mesh.faces.data(), GL_STATIC_DRAW);
    index_count_ = static_cast<GLsizei>(mesh.faces.size() * 3);

    // clip_from_world = projection (pinhole intrinsics, y down -> NDC y up) * cam_from_world.
    const Camera camera = BenchCamera();
    const double fx = camera.params[0], fy = camera.params[1], cx = camera.params[2],
                 cy = camera.params[3], near = 0.1, far = 10.0;
    Eigen::Matrix4d projection = Eigen::Matrix4d::Zero();
    projection(0, 0) = 2 * fx / kWidth;
    projection(0, 2) = 2 * cx / kWidth - 1;
    projection(1, 1) = -2 * fy / kHeight;
    projection(1, 2) = 1 - 2 * cy / kHeight;
    projection(2, 2) = (far + near) / (far - near);
    projection(2, 3) = -2 * far * near / (far - near);
    projection(3, 2) = 1;
    const Pose pose = BenchPose();
    Eigen::Matrix4d view = Eigen::Matrix4d::Identity();
    view.topLeftCorner<3, 3>() = pose.rotation;
    view.topRightCorner<3, 1>() = pose.translation;
    const Eigen::Matrix4f clip_from_world = (projection * view).cast<float>();
    glUniformMatrix4fv(glGetUniformLocation(program_, "clip_from_world"), 1, GL_FALSE,
                       clip_from_world.data());  // Eigen is column-major, as GL expects
    glViewport(0, 0, kWidth, kHeight);
    glEnable(GL_DEPTH_TEST);
    if (samples > 0) glEnable(GL_MULTISAMPLE);
    pixels_.resize(static_cast<size_t>(kWidth) * kHeight * 4);
    return glGetError() == GL_NO_ERROR || Fail(error, "OpenGL error during setup");
  }

  // Draws one frame and reads it back (the rephoto renderer also ends with an image in memory).
  void Frame() {
    glBindFramebuffer(GL_FRAMEBUFFER, framebuffer_);
    glClearColor(0, 0, 0, 0);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glDrawElements(GL_TRIANGLES, index_count_, GL_UNSIGNED_INT, nullptr);
    if (samples_ > 0) {
      glBindFramebuffer(GL_READ_FRAMEBUFFER, framebuffer_);
      glBindFramebuffer(GL_DRAW_FRAMEBUFFER, resolve_framebuffer_);
      glBlitFramebuffer(0, 0, kWidth, kHeight, 0, 0, kWidth, kHeight, GL_COLOR_BUFFER_BIT,
                        GL_NEAREST);
      glBindFramebuffer(GL_READ_FRAMEBUFFER, resolve_framebuffer_);
    }
    glReadPixels(0, 0, kWidth, kHeight, GL_RGBA, GL_UNSIGNED_BYTE, pixels_.data());
  }

  double Coverage() const {
    size_t covered = 0;
    for (size_t i = 0; i < pixels_.size(); i += 4) covered += pixels_[i + 3];
    return covered / 255.0 / (pixels_.size() / 4);
  }
  const std::string& renderer_name() const { return renderer_name_; }

 private:
  static bool Fail(std::string* error, const char* message) {
    *error = message;
    return false;
  }
  EGLDisplay display_ = EGL_NO_DISPLAY;
  EGLContext context_ = EGL_NO_CONTEXT;
  GLuint framebuffer_ = 0, renderbuffers_[2] = {0, 0};
  GLuint resolve_framebuffer_ = 0, resolve_renderbuffer_ = 0;
  GLuint program_ = 0, vertex_array_ = 0;
  GLsizei index_count_ = 0;
  int samples_ = 0;
  std::string renderer_name_;
  std::vector<uint8_t> pixels_;
};

// OpenGL frame time, and in the same run the rephoto frame with the matching sample count
// (1x: 1 spp, 4x MSAA: 4 spp), interleaved; counters give both medians and their ratio.
void BM_OpenGlLlvmpipe(benchmark::State& state) {
  const int msaa = static_cast<int>(state.range(0));
  static std::unique_ptr<GlRenderer> renderers[2];
  auto& gl = renderers[msaa > 0 ? 1 : 0];
  if (gl == nullptr) {
    gl = std::make_unique<GlRenderer>();
    std::string error;
    if (!gl->Init(msaa, &error)) {
      gl.reset();
      state.SkipWithError(("OpenGL unavailable: " + error).c_str());
      return;
    }
  }
  const auto& model = BenchModel();
  const auto rays = model.RaysFor(BenchCamera());
  rephoto::render::RenderOptions options;
  options.samples_per_pixel = msaa > 0 ? msaa : 1;
  rephoto::render::Rephoto out;
  rephoto::render::RenderRephoto(model, *rays, BenchPose(), options, &out);
  gl->Frame();  // warm-up
  std::vector<double> gl_seconds, rephoto_seconds;
  for (auto _ : state) {
    auto start = std::chrono::steady_clock::now();
    gl->Frame();
    gl_seconds.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    state.PauseTiming();
    start = std::chrono::steady_clock::now();
    rephoto::render::RenderRephoto(model, *rays, BenchPose(), options, &out);
    rephoto_seconds.push_back(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
    state.ResumeTiming();
  }
  const double gl_ms = Median(gl_seconds) * 1e3, rephoto_ms = Median(rephoto_seconds) * 1e3;
  state.counters["gl_ms"] = gl_ms;
  state.counters["rephoto_ms"] = rephoto_ms;
  state.counters["gl_over_rephoto"] = gl_ms / rephoto_ms;
  state.counters["gl_coverage"] = gl->Coverage();
  state.counters["rephoto_coverage"] = Coverage(out.color);
  state.SetLabel(gl->renderer_name());
}
BENCHMARK(BM_OpenGlLlvmpipe)->Arg(0)->Arg(4)->Unit(benchmark::kMillisecond)->Iterations(10);
#endif

}  // namespace

int main(int argc, char** argv) {
  rephoto::KeepFreedMemory();  // as the rephoto CLI runs
  const char* threads = std::getenv("REPHOTO_BENCH_THREADS");
  rephoto::ThreadLimit limit(threads != nullptr ? std::atoi(threads) : 0);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
