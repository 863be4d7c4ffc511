#include "rephoto/lpips/lpips.h"

#include <fmt/format.h>
#include <omp.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <mutex>
#include <oneapi/dnnl/dnnl.hpp>
#include <utility>

#include "rephoto/core/error.h"
#include "rephoto/core/limits.h"
#include "rephoto/core/parallel.h"
#include "rephoto/lpips/torch_file.h"

namespace rephoto::lpips {
namespace fs = std::filesystem;

namespace {

struct ConvSpec {
  int index;  // torchvision features.<index>
  int cin, cout, kernel, stride, pad;
};

// torchvision's AlexNet and VGG16 "features" and the slices the lpips package taps
// (lpips/pretrained_networks.py): alex slices [0,2) [2,5) [5,8) [8,10) [10,12); vgg16 [0,4)
// [4,9) [9,16) [16,23) [23,30). Pools: alex MaxPool2d(3, 2) at 2, 5; vgg MaxPool2d(2, 2) at 4,
// 9, 16, 23. Every conv is followed by a ReLU, which ends each slice.
struct StageSpec {
  int pool_kernel = 0, pool_stride = 0;  // 0 = no pool before the convs
  std::vector<ConvSpec> convs;
};

std::vector<StageSpec> Architecture(LpipsNet net) {
  if (net == LpipsNet::kAlex) {
    return {{0, 0, {{0, 3, 64, 11, 4, 2}}},
            {3, 2, {{3, 64, 192, 5, 1, 2}}},
            {3, 2, {{6, 192, 384, 3, 1, 1}}},
            {0, 0, {{8, 384, 256, 3, 1, 1}}},
            {0, 0, {{10, 256, 256, 3, 1, 1}}}};
  }
  return {{0, 0, {{0, 3, 64, 3, 1, 1}, {2, 64, 64, 3, 1, 1}}},
          {2, 2, {{5, 64, 128, 3, 1, 1}, {7, 128, 128, 3, 1, 1}}},
          {2, 2, {{10, 128, 256, 3, 1, 1}, {12, 256, 256, 3, 1, 1}, {14, 256, 256, 3, 1, 1}}},
          {2, 2, {{17, 256, 512, 3, 1, 1}, {19, 512, 512, 3, 1, 1}, {21, 512, 512, 3, 1, 1}}},
          {2, 2, {{24, 512, 512, 3, 1, 1}, {26, 512, 512, 3, 1, 1}, {28, 512, 512, 3, 1, 1}}}};
}

const FloatTensor& Take(const StateDict& dict, const fs::path& file, const std::string& key,
                        const std::vector<int64_t>& shape) {
  auto it = dict.find(key);
  REPHOTO_CHECK(it != dict.end(), "{}: no tensor '{}' (is this the right file?)", file.string(),
                key);
  REPHOTO_CHECK(it->second.shape == shape, "{}: tensor '{}' has shape [{}], expected [{}]",
                file.string(), key, fmt::join(it->second.shape, ", "), fmt::join(shape, ", "));
  REPHOTO_CHECK(!it->second.values.empty(), "{}: tensor '{}' is {}, not floating point",
                file.string(), key, it->second.dtype);
  for (float v : it->second.values) {
    REPHOTO_CHECK(std::isfinite(v), "{}: tensor '{}' holds a non-finite value", file.string(),
                  key);
  }
  return it->second;
}

// oneDNN's dispatch capped at AVX2, once per process (see the header).
void CapOneDnnIsa() {
  static std::once_flag once;
  std::call_once(once, [] {
    // An explicit ONEDNN_MAX_CPU_ISA (or its old name DNNL_MAX_CPU_ISA) is the user's choice.
    const char* onednn = std::getenv("ONEDNN_MAX_CPU_ISA");
    const char* dnnl = std::getenv("DNNL_MAX_CPU_ISA");
    if ((onednn != nullptr && *onednn != 0) || (dnnl != nullptr && *dnnl != 0)) {
      return;
    }
    // Fails (status not success) only when oneDNN already created kernels in this process
    // (another library using it first); then its own choice stands.
    (void)dnnl::set_max_cpu_isa(dnnl::cpu_isa::avx2);
  });
}

const dnnl::engine& Engine() {
  static const dnnl::engine engine(dnnl::engine::kind::cpu, 0);
  return engine;
}

using Tag = dnnl::memory::format_tag;
using Dt = dnnl::memory::data_type;

}  // namespace

std::string_view LpipsNetName(LpipsNet net) { return net == LpipsNet::kAlex ? "alex" : "vgg"; }

std::optional<LpipsNet> ParseLpipsNet(std::string_view name) {
  if (name == "alex" || name == "alexnet") return LpipsNet::kAlex;
  if (name == "vgg" || name == "vgg16") return LpipsNet::kVgg;
  return std::nullopt;
}

std::vector<std::string> LpipsWeightFiles(LpipsNet net) {
  if (net == LpipsNet::kAlex) return {"alex.pth", "alexnet-owt-7be5be79.pth"};
  return {"vgg.pth", "vgg16-397923af.pth"};
}

fs::path LpipsWeightsDirectory(const fs::path& option) {
  if (!option.empty()) return option;
  const char* env = std::getenv(kLpipsWeightsEnv);
  if (env != nullptr && *env != '\0') return fs::path(env);
  return {};
}

std::string MissingWeightsMessage(LpipsNet net, const fs::path& dir) {
  const std::vector<std::string> files = LpipsWeightFiles(net);
  const std::string where =
      dir.empty() ? fmt::format("no weights directory was given (--lpips-weights DIR, config key "
                                "lpips_weights, or ${})",
                                kLpipsWeightsEnv)
                  : fmt::format("looked in {}", dir.string());
  return fmt::format(
      "lpips ({}) needs the files {} and {} in one directory; {}. They are the files PyTorch "
      "users already have, used as they are: {} is in the lpips package (pip install lpips; "
      "<site-packages>/lpips/weights/v0.1/{}), {} is torchvision's checkpoint "
      "(~/.cache/torch/hub/checkpoints/{} once torchvision has loaded it, or "
      "https://download.pytorch.org/models/{}). rephoto downloads nothing.",
      LpipsNetName(net), files[0], files[1], where, files[0], files[0], files[1], files[1],
      files[1]);
}

std::shared_ptr<const LpipsModel> LpipsModel::Load(const fs::path& dir, LpipsNet net) {
  REPHOTO_CHECK_USAGE(!dir.empty(), "{}", MissingWeightsMessage(net, dir));
  const std::vector<std::string> files = LpipsWeightFiles(net);
  for (const std::string& file : files) {
    std::error_code ec;
    REPHOTO_CHECK_USAGE(fs::is_regular_file(dir / file, ec), "{}",
                        MissingWeightsMessage(net, dir));
  }
  CapOneDnnIsa();
  const fs::path lin_file = dir / files[0], backbone_file = dir / files[1];
  const StateDict lin = ReadTorchFile(lin_file);
  const StateDict backbone = ReadTorchFile(backbone_file);
  std::shared_ptr<LpipsModel> model(new LpipsModel());
  model->net_ = net;
  const std::vector<StageSpec> arch = Architecture(net);
  for (size_t s = 0; s < arch.size(); ++s) {
    Stage stage;
    if (arch[s].pool_kernel > 0) {
      Op op;
      op.pool = true;
      op.pool_kernel = arch[s].pool_kernel;
      op.pool_stride = arch[s].pool_stride;
      stage.ops.push_back(op);
    }
    for (const ConvSpec& spec : arch[s].convs) {
      Conv conv;
      conv.cin = spec.cin;
      conv.cout = spec.cout;
      conv.kernel = spec.kernel;
      conv.stride = spec.stride;
      conv.pad = spec.pad;
      conv.weight = Take(backbone, backbone_file, fmt::format("features.{}.weight", spec.index),
                         {spec.cout, spec.cin, spec.kernel, spec.kernel})
                        .values;
      conv.bias =
          Take(backbone, backbone_file, fmt::format("features.{}.bias", spec.index), {spec.cout})
              .values;
      Op op;
      op.conv = static_cast<int>(model->convs_.size());
      model->convs_.push_back(std::move(conv));
      stage.ops.push_back(op);
      stage.channels = spec.cout;
    }
    stage.lin = Take(lin, lin_file, fmt::format("lin{}.model.1.weight", s),
                     {1, stage.channels, 1, 1})
                    .values;
    model->stages_.push_back(std::move(stage));
  }
  return model;
}

std::shared_ptr<const LpipsModel> LpipsModel::LoadShared(const fs::path& dir, LpipsNet net) {
  static std::mutex mutex;
  static std::map<std::pair<std::string, int>, std::shared_ptr<const LpipsModel>> cache;
  std::error_code ec;
  fs::path key_path = dir.empty() ? dir : fs::weakly_canonical(dir, ec);
  if (ec) key_path = dir;
  const std::pair<std::string, int> key(key_path.string(), static_cast<int>(net));
  std::lock_guard<std::mutex> lock(mutex);
  auto it = cache.find(key);
  if (it != cache.end()) return it->second;
  std::shared_ptr<const LpipsModel> model = Load(dir, net);
  cache.emplace(key, model);
  return model;
}

namespace {

struct Dims {
  int64_t c, h, w;
};

dnnl::memory::desc Nhwc(const Dims& d) {
  return dnnl::memory::desc({1, d.c, d.h, d.w}, Dt::f32, Tag::nhwc);
}

// One stage's primitives, the same for both images.
struct StagePlan {
  struct Step {
    dnnl::primitive primitive;
    dnnl::memory::desc dst;
    dnnl::memory weights, bias;  // conv only
    bool conv = false;
    bool reorder = false;
  };
  std::vector<Step> steps;
  Dims out{};
};

// Writes the network input for `view`: 2x - 1, then the ScalingLayer, in float as PyTorch does.
void FillInput(const metrics::RgbView& view, float* out) {
  static constexpr float kShift[3] = {-.030f, -.088f, -.188f};
  static constexpr float kScale[3] = {.458f, .448f, .450f};
  const int64_t w = view.width(), h = view.height(), channels = view.channels();
  ParallelFor(0, h, 16, [&](int64_t y0, int64_t y1) {
    for (int64_t y = y0; y < y1; ++y) {
      for (int64_t x = 0; x < w; ++x) {
        const int64_t i = y * w + x;
        for (int c = 0; c < 3; ++c) {
          float v = view.floats() ? view.floats()[i * channels + c]
                                  : static_cast<float>(view.bytes()[i * channels + c]) / 255.f;
          v = 2.f * v - 1.f;
          out[3 * i + c] = (v - kShift[c]) / kScale[c];
        }
      }
    }
  });
}

}  // namespace

LpipsValue LpipsModel::Compute(const metrics::RgbView& a, const metrics::RgbView& b,
                               const Mask* mask, Image* spatial_map, bool masked) const {
  const int width = a.width(), height = a.height();
  REPHOTO_CHECK(b.width() == width && b.height() == height,
                "lpips: images differ in size ({}x{} and {}x{})", width, height, b.width(),
                b.height());
  REPHOTO_CHECK(a.channels() >= 3 && b.channels() >= 3, "lpips: images must be RGB or RGBA");
  REPHOTO_CHECK(mask == nullptr || mask->empty() ||
                    (mask->width() == width && mask->height() == height),
                "lpips: mask is {}x{}, images {}x{}", mask ? mask->width() : 0,
                mask ? mask->height() : 0, width, height);

  // Shapes of every stage, the size check and the memory check before any allocation.
  std::vector<Dims> taps;
  uint64_t peak = 0;
  uint64_t largest = 0;  // bytes of the largest activation (the input included)
  {
    Dims d{3, height, width};
    largest = SaturatingMultiply(static_cast<uint64_t>(width) * height, 12);
    for (const Stage& stage : stages_) {
      for (const Op& op : stage.ops) {
        if (op.pool) {
          d.h = d.h >= op.pool_kernel ? (d.h - op.pool_kernel) / op.pool_stride + 1 : 0;
          d.w = d.w >= op.pool_kernel ? (d.w - op.pool_kernel) / op.pool_stride + 1 : 0;
        } else {
          const Conv& c = convs_[op.conv];
          const int64_t h = d.h + 2 * c.pad - c.kernel, w = d.w + 2 * c.pad - c.kernel;
          d = Dims{c.cout, h >= 0 ? h / c.stride + 1 : 0, w >= 0 ? w / c.stride + 1 : 0};
        }
        REPHOTO_CHECK(d.h > 0 && d.w > 0,
                      "lpips ({}): a {}x{} image is too small for the network (AlexNet needs "
                      "at least 31x31 pixels, VGG16 16x16)",
                      LpipsNetName(net_), width, height);
        largest = std::max(largest, SaturatingMultiply(static_cast<uint64_t>(d.c * 4),
                                                       static_cast<uint64_t>(d.h * d.w)));
      }
      taps.push_back(d);
    }
    // Two images' activations plus one being made, and the layer maps in double.
    peak = SaturatingMultiply(largest, 3) +
           SaturatingMultiply(static_cast<uint64_t>(width) * height, 8);
  }
  CheckAllocation("lpips", fmt::format("{}x{} images through {}", width, height,
                                       LpipsNetName(net_)),
                  peak);

  // oneDNN threads: as many as the calling TBB arena may use.
  omp_set_num_threads(std::max(1, tbb::this_task_arena::max_concurrency()));
  const dnnl::engine& engine = Engine();
  dnnl::stream stream(engine);

  // Activations live in three slots of the largest activation's size, kept by the calling
  // thread for its next calls (first touch of fresh pages costs ~10 us per 4 KiB on the target
  // machines: 12% of AlexNet at 12 MP when allocated per call): one holds each image's current
  // activation, the third receives the next step's output (then the source slot is free).
  struct Slots {
    std::unique_ptr<float[]> data[3];
    uint64_t floats = 0;
  };
  thread_local Slots slots;
  if (slots.floats < largest / 4) {
    for (auto& slot : slots.data) slot.reset();
    for (auto& slot : slots.data) slot.reset(new float[largest / 4]);
    slots.floats = largest / 4;
  }
  int owner[2] = {0, 1}, free_slot = 2;
  dnnl::memory act[2];
  for (int i = 0; i < 2; ++i) {
    act[i] = dnnl::memory(Nhwc({3, height, width}), engine, slots.data[owner[i]].get());
    FillInput(i == 0 ? a : b, slots.data[owner[i]].get());
  }

  std::vector<std::vector<double>> maps(stages_.size());
  std::vector<double> layer_means(stages_.size());
  Dims in{3, height, width};
  dnnl::memory::desc cur = Nhwc(in);  // layout of act[] between steps
  for (size_t s = 0; s < stages_.size(); ++s) {
    const Stage& stage = stages_[s];
    // Primitives of the stage.
    StagePlan plan;
    Dims d = in;
    // A reorder of the activation from `cur` to `want` when they differ.
    const auto convert = [&](const dnnl::memory::desc& want) {
      if (want == cur) return;
      StagePlan::Step step;
      step.primitive = dnnl::reorder(dnnl::reorder::primitive_desc(engine, cur, engine, want));
      step.dst = want;
      step.reorder = true;
      plan.steps.push_back(std::move(step));
      cur = want;
    };
    for (const Op& op : stage.ops) {
      StagePlan::Step step;
      if (op.pool) {
        const Dims out{d.c, (d.h - op.pool_kernel) / op.pool_stride + 1,
                       (d.w - op.pool_kernel) / op.pool_stride + 1};
        const dnnl::pooling_forward::desc desc(
            dnnl::prop_kind::forward_inference, dnnl::algorithm::pooling_max, cur,
            Nhwc(out), {op.pool_stride, op.pool_stride},
            {op.pool_kernel, op.pool_kernel}, {0, 0}, {0, 0});
        const dnnl::pooling_forward::primitive_desc pd(desc, engine);
        step.primitive = dnnl::pooling_forward(pd);
        step.dst = pd.dst_desc();
        d = out;
      } else {
        const Conv& c = convs_[op.conv];
        const Dims out{c.cout, (d.h + 2 * c.pad - c.kernel) / c.stride + 1,
                       (d.w + 2 * c.pad - c.kernel) / c.stride + 1};
        const dnnl::memory::desc weights_any({c.cout, c.cin, c.kernel, c.kernel}, Dt::f32,
                                             Tag::any);
        const dnnl::memory::desc bias_md({c.cout}, Dt::f32, Tag::x);
        const dnnl::convolution_forward::desc desc(
            dnnl::prop_kind::forward_inference, dnnl::algorithm::convolution_direct,
            Nhwc(d), weights_any, bias_md, Nhwc(out),
            {c.stride, c.stride}, {c.pad, c.pad}, {c.pad, c.pad});
        dnnl::post_ops post;
        post.append_eltwise(1.f, dnnl::algorithm::eltwise_relu, 0.f, 0.f);
        dnnl::primitive_attr attr;
        attr.set_post_ops(post);
        const dnnl::convolution_forward::primitive_desc pd(desc, attr, engine);
        convert(pd.src_desc());
        const dnnl::memory::desc user_weights({c.cout, c.cin, c.kernel, c.kernel}, Dt::f32,
                                              Tag::oihw);
        dnnl::memory user(user_weights, engine, const_cast<float*>(c.weight.data()));
        step.weights = dnnl::memory(pd.weights_desc(), engine);
        dnnl::reorder(user, step.weights).execute(stream, user, step.weights);
        step.bias = dnnl::memory(bias_md, engine, const_cast<float*>(c.bias.data()));
        step.primitive = dnnl::convolution_forward(pd);
        step.dst = pd.dst_desc();
        step.conv = true;
        d = out;
      }
      cur = step.dst;
      plan.steps.push_back(std::move(step));
    }
    plan.out = d;
    // Both images through the stage.
    for (int i = 0; i < 2; ++i) {
      for (StagePlan::Step& step : plan.steps) {
        REPHOTO_CHECK(step.dst.get_size() <= slots.floats * sizeof(float),
                      "lpips: internal error: an activation of {} bytes exceeds its slot",
                      step.dst.get_size());
        dnnl::memory dst(step.dst, engine, slots.data[free_slot].get());
        std::swap(free_slot, owner[i]);
        if (step.conv) {
          step.primitive.execute(stream, {{DNNL_ARG_SRC, act[i]},
                                          {DNNL_ARG_WEIGHTS, step.weights},
                                          {DNNL_ARG_BIAS, step.bias},
                                          {DNNL_ARG_DST, dst}});
        } else if (step.reorder) {
          step.primitive.execute(stream, {{DNNL_ARG_FROM, act[i]}, {DNNL_ARG_TO, dst}});
        } else {
          step.primitive.execute(stream, {{DNNL_ARG_SRC, act[i]}, {DNNL_ARG_DST, dst}});
        }
        stream.wait();
        act[i] = dst;
      }
    }
    in = d;
    // The tapped features in NHWC (channels of a position contiguous).
    dnnl::memory tap[2];
    for (int i = 0; i < 2; ++i) {
      if (cur == Nhwc(d)) {
        tap[i] = act[i];
      } else {
        tap[i] = dnnl::memory(Nhwc(d), engine);
        dnnl::reorder(act[i], tap[i]).execute(stream, act[i], tap[i]);
        stream.wait();
      }
    }
    // d_l per position: unit-normalised features, squared difference, the lin layer.
    const int64_t channels = d.c, h = d.h, w = d.w;
    const float* f0 = static_cast<const float*>(tap[0].get_data_handle());
    const float* f1 = static_cast<const float*>(tap[1].get_data_handle());
    const float* lin = stage.lin.data();
    std::vector<double>& map = maps[s];
    map.resize(static_cast<size_t>(h * w));
    std::vector<double> row_sums(static_cast<size_t>(h));
    ParallelFor(0, h, 1, [&](int64_t y0, int64_t y1) {
      for (int64_t y = y0; y < y1; ++y) {
        double row = 0;
        for (int64_t x = 0; x < w; ++x) {
          const float* p = f0 + (y * w + x) * channels;
          const float* q = f1 + (y * w + x) * channels;
          double s0 = 0, s1 = 0;
          for (int64_t c = 0; c < channels; ++c) {
            s0 += static_cast<double>(p[c]) * p[c];
            s1 += static_cast<double>(q[c]) * q[c];
          }
          const double n0 = 1.0 / (std::sqrt(s0) + 1e-10), n1 = 1.0 / (std::sqrt(s1) + 1e-10);
          double value = 0;
          for (int64_t c = 0; c < channels; ++c) {
            const double diff = p[c] * n0 - q[c] * n1;
            value += lin[c] * diff * diff;
          }
          map[static_cast<size_t>(y * w + x)] = value;
          row += value;
        }
        row_sums[static_cast<size_t>(y)] = row;
      }
    });
    double sum = 0;
    for (double r : row_sums) sum += r;
    layer_means[s] = sum / static_cast<double>(h * w);
  }
  act[0] = dnnl::memory();
  act[1] = dnnl::memory();

  LpipsValue result;
  for (double m : layer_means) result.whole += m;
  if (!masked && spatial_map == nullptr) {
    result.masked = std::numeric_limits<double>::quiet_NaN();
    return result;
  }

  // The spatial map: each layer's map upsampled bilinearly (align_corners=False, as
  // torch.nn.Upsample(size=..., mode='bilinear')) to width x height and summed.
  struct Axis {
    std::vector<int> i0, i1;
    std::vector<double> t;
  };
  const auto axis = [](int64_t in_size, int64_t out_size) {
    Axis ax;
    ax.i0.resize(out_size);
    ax.i1.resize(out_size);
    ax.t.resize(out_size);
    const double scale = static_cast<double>(in_size) / static_cast<double>(out_size);
    for (int64_t o = 0; o < out_size; ++o) {
      double src = (static_cast<double>(o) + 0.5) * scale - 0.5;
      if (src < 0) src = 0;
      int i0 = static_cast<int>(src);
      if (i0 > in_size - 1) i0 = static_cast<int>(in_size - 1);
      ax.i0[o] = i0;
      ax.i1[o] = i0 < in_size - 1 ? i0 + 1 : i0;
      ax.t[o] = src - i0;
    }
    return ax;
  };
  std::vector<Axis> xs, ys;
  for (const Dims& t : taps) {
    xs.push_back(axis(t.w, width));
    ys.push_back(axis(t.h, height));
  }
  if (spatial_map) spatial_map->Resize(width, height, 1);
  const bool all_valid = mask == nullptr || mask->empty();
  std::vector<double> row_sums(static_cast<size_t>(height));
  std::vector<size_t> row_counts(static_cast<size_t>(height));
  ParallelFor(0, height, 8, [&](int64_t y0, int64_t y1) {
    std::vector<double> row(static_cast<size_t>(width));
    for (int64_t y = y0; y < y1; ++y) {
      std::fill(row.begin(), row.end(), 0.0);
      for (size_t l = 0; l < taps.size(); ++l) {
        const Axis& ax = xs[l];
        const int64_t tw = taps[l].w;
        const double ty = ys[l].t[y];
        const double* r0 = maps[l].data() + ys[l].i0[y] * tw;
        const double* r1 = maps[l].data() + ys[l].i1[y] * tw;
        for (int64_t x = 0; x < width; ++x) {
          const double top = r0[ax.i0[x]] * (1 - ax.t[x]) + r0[ax.i1[x]] * ax.t[x];
          const double bottom = r1[ax.i0[x]] * (1 - ax.t[x]) + r1[ax.i1[x]] * ax.t[x];
          row[x] += top * (1 - ty) + bottom * ty;
        }
      }
      double sum = 0;
      size_t count = 0;
      const uint8_t* m = all_valid ? nullptr : mask->data() + y * width;
      for (int64_t x = 0; x < width; ++x) {
        if (m == nullptr || m[x]) {
          sum += row[x];
          ++count;
        }
      }
      row_sums[y] = sum;
      row_counts[y] = count;
      if (spatial_map) {
        float* out = spatial_map->row(static_cast<int>(y));
        for (int64_t x = 0; x < width; ++x) out[x] = static_cast<float>(row[x]);
      }
    }
  });
  double sum = 0;
  for (int y = 0; y < height; ++y) {
    sum += row_sums[y];
    result.masked_pixels += row_counts[y];
  }
  result.masked = result.masked_pixels > 0 ? sum / static_cast<double>(result.masked_pixels)
                                           : std::numeric_limits<double>::quiet_NaN();
  return result;
}

}  // namespace rephoto::lpips
