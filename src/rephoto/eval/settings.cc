#include "rephoto/eval/settings.h"

#include <toml++/toml.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <sstream>

#include "rephoto/core/file.h"
#include "rephoto/eval/command_template.h"
#include "rephoto/splat/rasterize.h"

namespace rephoto::eval {
namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;

const std::vector<SettingInfo>& Settings() {
  static const std::vector<SettingInfo> settings = {
      {"scene", SettingType::kPath, "Scene file or folder with the cameras (any format)"},
      {"format", SettingType::kString, "Scene format instead of detection"},
      {"image-root", SettingType::kPath, "Folder the image names are relative to"},
      {"scheme", SettingType::kString,
       "Split: kfold:K[:SEED] (seeded shuffle: a fold may hold out neighbouring photos), "
       "interleaved:K (photo i, by name, tested in fold i mod K: neighbours in different "
       "folds), loo, every:N, fraction:F[:SEED], lists:TRAIN,TEST, none (default: none for a "
       "model alone, else kfold:5)"},
      {"model", SettingType::kPath,
       "Model file (mesh/point cloud) for all folds; with --reconstruct the model's path "
       "inside {out}"},
      {"reconstruct", SettingType::kString,
       "Command run per fold (/bin/sh -c) with placeholders {train} {sparse} {transforms} "
       "{images} {train_list} {test} {test_sparse} {test_transforms} {test_list} {out} {fold} "
       "{threads}"},
      {"render", SettingType::kString,
       "External renderer command per fold writing RGBA <test stem>.<png|jpg|exr|pfm> into "
       "{out} (placeholders as --reconstruct)"},
      {"representation", SettingType::kString,
       "Built-in renderer: auto (the model: mesh, point cloud or 3D Gaussians, detected), "
       "gaussians (the model as 3D Gaussian splats), vdt (view-dependent "
       "texturing of the fold's training photos on the model), ibr (training photos warped by "
       "depth maps; no model needed; its plane sweep takes about 20x vdt's time per fold: "
       "give --depth-maps or a lower --train-short-side to trade quality for time)"},
      {"depth-maps", SettingType::kPath,
       "ibr: folder of depth maps per training view (COLMAP .bin, PFM, EXR); default: plane "
       "sweep"},
      {"colorize", SettingType::kBool,
       "Colour each fold's mesh from that fold's training photos before rendering"},
      {"texture", SettingType::kBool,
       "Texture each fold's mesh from that fold's training photos before rendering (Waechter "
       "et al. 2014, texture/texture_mesh.h): the paper's textured row, cross-validated"},
      {"texture-noise", SettingType::kDouble,
       "Defect: offset colours/texels by simplex noise of this maximum (colour units)"},
      {"geometry-noise", SettingType::kDouble,
       "Defect: move vertices along normals by simplex noise, max fraction of the extent"},
      {"simplify", SettingType::kDouble, "Defect: remove this fraction of the faces, in [0,1)"},
      {"defect-seed", SettingType::kInt, "Seed of the defects' noise"},
      {"train-count", SettingType::kInt,
       "Train each fold on a seeded subset of N training views (0 = all)"},
      {"train-seed", SettingType::kInt, "Seed of the --train-count subsets"},
      {"train-short-side", SettingType::kInt,
       "Downscale training photos to this shorter side in pixels (0 = original)"},
      {"eval-short-side", SettingType::kInt,
       "Render and compare at this shorter side in pixels (0 = original)"},
      {"metrics", SettingType::kMetricList,
       "Metrics (1-ncc,cb+cr,zssd,dssim,census,icid,psnr,ssim,lpips) or all (every metric but "
       "lpips, which needs --lpips-weights)"},
      {"compat", SettingType::kString,
       "Also compute the numbers papers publish, as 3dgs (graphdeco's metrics.py) or "
       "nerfstudio (ns-eval) does: whole-image PSNR/SSIM beside rephoto's masked metrics, in "
       "their own files (results.json, per_view.json / output.json); default split every:8 "
       "(none = off)"},
      {"compat-metrics", SettingType::kMetricList,
       "The --compat preset's metrics to compute, among psnr,ssim,lpips (default: psnr,ssim, and lpips when LPIPS weights are given)"},
      {"lpips-weights", SettingType::kPath,
       "Folder with the LPIPS weight files under their original names (alex.pth + "
       "alexnet-owt-7be5be79.pth; vgg.pth + vgg16-397923af.pth); default: "
       "$REPHOTO_LPIPS_WEIGHTS (docs/lpips.md)"},
      {"lpips-net", SettingType::kString, "LPIPS network: alex or vgg"},
      {"window", SettingType::kInt, "Window side of 1-ncc, zssd, census and completeness (odd)"},
      {"ssim-mode", SettingType::kString,
       "SSIM/DSSIM window: gaussian (11x11, sigma 1.5) or skimage (7x7 uniform)"},
      {"dark", SettingType::kDouble, "Photo pixels with any channel <= this are ill-exposed"},
      {"saturated", SettingType::kDouble, "Photo pixels with any channel >= this are ill-exposed"},
      {"photo-masks", SettingType::kPath,
       "Folder of photo masks by stem (0 = ignore the pixel); default: the scene's masks"},
      {"resize", SettingType::kBool, "Rescale external renderings of another size to the photo"},
      {"error-images", SettingType::kBool, "Write errors/<stem>.<metric>.exr/.png"},
      {"error-image-metrics", SettingType::kMetricList,
       "Write error images of these metrics (and of the projection metric), or all (default: "
       "the headline metric, 1-NCC when measured, and the projection metric)"},
      {"depth-images", SettingType::kBool,
       "Write renders/<stem>.depth.exr beside each built-in rendering (nothing in the run reads "
       "them)"},
      {"spp", SettingType::kInt, "Samples per pixel of the built-in renderer"},
      {"backfaces", SettingType::kBool, "Render the back sides of triangles"},
      {"point-radius", SettingType::kDouble,
       "Splat radius of point clouds in model units (0 = the file's, else from the density)"},
      {"point-neighbors", SettingType::kInt, "k of the k-th nearest neighbour splat radius"},
      {"gaussian-mode", SettingType::kString,
       "Gaussian splatting models: classic (graphdeco's rasterizer) or antialiased (gsplat's)"},
      {"background", SettingType::kString,
       "Training background R,G,B in [0,1], black or white: Gaussian splatting models are "
       "rendered over it, and --compat composites photos with alpha over it"},
      {"min-alpha", SettingType::kDouble,
       "Gaussian splatting models: a pixel counts as rendered (completeness) when its alpha "
       "reaches this"},
      {"out", SettingType::kPath, "Run directory"},
      {"jobs", SettingType::kInt, "Folds whose external commands run at once"},
      {"command-timeout", SettingType::kDouble,
       "Seconds a fold's --reconstruct/--render command may run; then it is stopped and the "
       "fold fails (0 = no limit)"},
      {"projection-metric", SettingType::kString,
       "Metric projected onto the model (none = no projection)"},
      {"report", SettingType::kBool, "Write report.html"},
  };
  return settings;
}

namespace {

std::string Canonical(std::string_view name) {
  std::string canonical(name);
  for (char& c : canonical) {
    if (c == '_') c = '-';
  }
  return canonical;
}

const SettingInfo* FindSetting(std::string_view name) {
  const std::string canonical = Canonical(name);
  for (const SettingInfo& info : Settings()) {
    if (info.name == canonical) return &info;
  }
  return nullptr;
}

std::string KnownNames() {
  std::string names;
  for (const SettingInfo& info : Settings()) {
    if (!names.empty()) names += ", ";
    names += info.name;
  }
  return names;
}

const char* TypeName(const SettingValue& value) {
  switch (value.index()) {
    case 0:
      return "a string";
    case 1:
      return "an integer";
    case 2:
      return "a number";
    case 3:
      return "a boolean";
    default:
      return "an array";
  }
}

std::string AsString(const SettingValue& value, std::string_view source) {
  if (const auto* s = std::get_if<std::string>(&value)) return *s;
  throw UsageError(fmt::format("{}: expected a string, got {}", source, TypeName(value)));
}

int64_t AsInt(const SettingValue& value, std::string_view source) {
  if (const auto* i = std::get_if<int64_t>(&value)) return *i;
  if (const auto* s = std::get_if<std::string>(&value)) {
    int64_t parsed = 0;
    const auto [end, ec] = std::from_chars(s->data(), s->data() + s->size(), parsed);
    if (ec == std::errc() && end == s->data() + s->size() && !s->empty()) return parsed;
    throw UsageError(fmt::format("{}: '{}' is not an integer", source, *s));
  }
  throw UsageError(fmt::format("{}: expected an integer, got {}", source, TypeName(value)));
}

double AsDouble(const SettingValue& value, std::string_view source) {
  if (const auto* d = std::get_if<double>(&value)) return *d;
  if (const auto* i = std::get_if<int64_t>(&value)) return static_cast<double>(*i);
  if (const auto* s = std::get_if<std::string>(&value)) {
    try {
      size_t used = 0;
      const double parsed = std::stod(*s, &used);
      if (used == s->size()) return parsed;
    } catch (const std::exception&) {
    }
    throw UsageError(fmt::format("{}: '{}' is not a number", source, *s));
  }
  throw UsageError(fmt::format("{}: expected a number, got {}", source, TypeName(value)));
}

bool AsBool(const SettingValue& value, std::string_view source) {
  if (const auto* b = std::get_if<bool>(&value)) return *b;
  if (const auto* s = std::get_if<std::string>(&value)) {
    if (*s == "true" || *s == "1" || *s == "yes") return true;
    if (*s == "false" || *s == "0" || *s == "no") return false;
    throw UsageError(fmt::format("{}: '{}' is not a boolean (true/false)", source, *s));
  }
  throw UsageError(fmt::format("{}: expected a boolean, got {}", source, TypeName(value)));
}

fs::path AsPath(const SettingValue& value, std::string_view source, const fs::path& base_dir) {
  fs::path path = AsString(value, source);
  if (!path.empty() && path.is_relative() && !base_dir.empty()) path = base_dir / path;
  return path;
}

int CheckedInt(const SettingValue& value, std::string_view source, int64_t low, int64_t high) {
  const int64_t v = AsInt(value, source);
  if (v < low || v > high) {
    throw UsageError(fmt::format("{}: {} is out of range [{}, {}]", source, v, low, high));
  }
  return static_cast<int>(v);
}

std::vector<metrics::Metric> AsMetrics(const SettingValue& value, std::string_view source) {
  std::string list;
  if (const auto* items = std::get_if<std::vector<std::string>>(&value)) {
    for (const std::string& item : *items) list += (list.empty() ? "" : ",") + item;
  } else {
    list = AsString(value, source);
  }
  try {
    std::vector<metrics::Metric> parsed = metrics::ParseMetricList(list);
    if (parsed.empty()) throw UsageError(fmt::format("{}: no metric given", source));
    return parsed;
  } catch (const UsageError&) {
    throw;
  } catch (const Error& e) {
    // metrics::ParseMetricList names the flag itself; the source (a flag or a file) replaces it.
    std::string_view why = e.what();
    if (why.starts_with("--metrics: ")) why.remove_prefix(11);
    throw UsageError(fmt::format("{}: {}", source, why));
  }
}

}  // namespace

void ApplySetting(EvaluateOptions* o, std::string_view name, const SettingValue& value,
                  std::string_view source, const fs::path& base_dir) {
  const SettingInfo* info = FindSetting(name);
  if (info == nullptr) {
    throw UsageError(
        fmt::format("{}: unknown setting '{}' (known: {})", source, name, KnownNames()));
  }
  const std::string& n = info->name;
  constexpr int64_t kMaxPixels = 1 << 20;
  if (n == "scene") {
    o->scene = AsPath(value, source, base_dir);
  } else if (n == "format") {
    o->format = AsString(value, source);
  } else if (n == "image-root") {
    o->image_root = AsPath(value, source, base_dir);
  } else if (n == "scheme") {
    o->scheme = AsString(value, source);
  } else if (n == "model") {
    // Kept as given: a model file, or with a reconstruct command a path inside {out};
    // LoadConfigFile resolves a model file against the config file's folder.
    o->model = AsString(value, source);
  } else if (n == "reconstruct") {
    o->reconstruct = AsString(value, source);
  } else if (n == "render") {
    o->render = AsString(value, source);
  } else if (n == "representation") {
    const std::string name = AsString(value, source);
    const std::optional<render::ViewRepresentation> representation =
        render::ParseRepresentation(name);
    if (!representation) {
      throw UsageError(fmt::format(
          "{}: '{}' is not one of auto (the model as it is), vdt (view-dependent texturing on "
          "the model), ibr (image-based rendering with depth maps), gaussians (the model as 3D "
          "Gaussian splats)",
          source, name));
    }
    o->representation = *representation;
  } else if (n == "depth-maps") {
    o->depth_maps = AsPath(value, source, base_dir);
  } else if (n == "colorize") {
    o->colorize = AsBool(value, source);
  } else if (n == "texture") {
    o->texture = AsBool(value, source);
  } else if (n == "texture-noise" || n == "geometry-noise" || n == "simplify") {
    const double v = AsDouble(value, source);
    if (!(v >= 0) || (n == "simplify" && !(v < 1))) {
      throw UsageError(fmt::format("{}: {} is out of range ({})", source, v,
                                   n == "simplify" ? "[0, 1)" : ">= 0"));
    }
    float& target = n == "texture-noise"    ? o->degrade.texture_noise
                    : n == "geometry-noise" ? o->degrade.geometry_noise
                                            : o->degrade.simplify;
    target = static_cast<float>(v);
  } else if (n == "defect-seed") {
    const int64_t seed = AsInt(value, source);
    if (seed < 0) throw UsageError(fmt::format("{}: the seed must not be negative", source));
    o->degrade.seed = static_cast<uint64_t>(seed);
  } else if (n == "train-count") {
    o->train_count = CheckedInt(value, source, 0, 1 << 30);
  } else if (n == "train-seed") {
    const int64_t seed = AsInt(value, source);
    if (seed < 0) throw UsageError(fmt::format("{}: the seed must not be negative", source));
    o->train_seed = static_cast<uint64_t>(seed);
  } else if (n == "train-short-side") {
    o->train_short_side = CheckedInt(value, source, 0, kMaxPixels);
  } else if (n == "eval-short-side") {
    o->eval_short_side = CheckedInt(value, source, 0, kMaxPixels);
  } else if (n == "metrics") {
    o->metrics = AsMetrics(value, source);
  } else if (n == "compat") {
    const std::string name = AsString(value, source);
    if (name.empty() || name == "none") {
      o->compat.reset();
    } else {
      o->compat = metrics::ParseCompatPreset(name);
      if (!o->compat) {
        throw UsageError(fmt::format("{}: '{}' is not 3dgs, nerfstudio or none", source, name));
      }
    }
  } else if (n == "compat-metrics") {
    // An empty list (as SettingsJson writes it without a preset) is the preset's default.
    const auto* items = std::get_if<std::vector<std::string>>(&value);
    const auto* text = std::get_if<std::string>(&value);
    if ((items && items->empty()) || (text && text->empty())) {
      o->compat_metrics.clear();
    } else {
      o->compat_metrics = AsMetrics(value, source);
    }
  } else if (n == "lpips-weights") {
    o->lpips_weights = AsPath(value, source, base_dir);
  } else if (n == "lpips-net") {
    const std::string net = AsString(value, source);
    const std::optional<lpips::LpipsNet> parsed = lpips::ParseLpipsNet(net);
    if (!parsed) throw UsageError(fmt::format("{}: '{}' is not alex or vgg", source, net));
    o->lpips_net = *parsed;
  } else if (n == "window") {
    const int window = CheckedInt(value, source, 3, 101);
    if (window % 2 == 0) throw UsageError(fmt::format("{}: the window must be odd", source));
    o->metric_options.window = window;
  } else if (n == "ssim-mode") {
    const std::string mode = AsString(value, source);
    if (mode == "gaussian") {
      o->metric_options.ssim_gaussian = true;
      o->metric_options.ssim_window = metrics::MetricOptions{}.ssim_window;
    } else if (mode == "skimage") {
      o->metric_options.ssim_gaussian = false;
      o->metric_options.ssim_window = 7;
    } else {
      throw UsageError(fmt::format("{}: '{}' is not gaussian or skimage", source, mode));
    }
  } else if (n == "dark") {
    o->exposure.dark_threshold = static_cast<float>(AsDouble(value, source));
  } else if (n == "saturated") {
    o->exposure.saturated_threshold = static_cast<float>(AsDouble(value, source));
  } else if (n == "photo-masks") {
    o->photo_masks = AsPath(value, source, base_dir);
  } else if (n == "resize") {
    o->resize = AsBool(value, source);
  } else if (n == "error-images") {
    o->error_images = AsBool(value, source);
  } else if (n == "error-image-metrics") {
    o->error_image_metrics = AsMetrics(value, source);
  } else if (n == "depth-images") {
    o->depth_images = AsBool(value, source);
  } else if (n == "spp") {
    o->samples_per_pixel = CheckedInt(value, source, 1, 1024);
  } else if (n == "backfaces") {
    o->backfaces = AsBool(value, source);
  } else if (n == "point-radius") {
    const double radius = AsDouble(value, source);
    if (!(radius >= 0) || !std::isfinite(radius)) {
      throw UsageError(fmt::format("{}: the radius must be >= 0", source));
    }
    o->point_radius = static_cast<float>(radius);
  } else if (n == "point-neighbors") {
    o->point_neighbors = CheckedInt(value, source, 1, 100);
  } else if (n == "gaussian-mode") {
    const std::string name = AsString(value, source);
    const std::optional<splat::GaussianMode> mode = splat::ParseGaussianMode(name);
    if (!mode) {
      throw UsageError(fmt::format("{}: '{}' is not classic or antialiased", source, name));
    }
    o->gaussian_mode = *mode;
  } else if (n == "background") {
    // "R,G,B", or a list of three numbers (a config array, a Python tuple).
    std::string text;
    if (const auto* items = std::get_if<std::vector<std::string>>(&value)) {
      for (const std::string& item : *items) text += (text.empty() ? "" : ",") + item;
    } else {
      text = AsString(value, source);
    }
    const Eigen::Vector3f rgb = splat::ParseBackground(text, source);
    o->background = {rgb[0], rgb[1], rgb[2]};
  } else if (n == "min-alpha") {
    const double min_alpha = AsDouble(value, source);
    if (!(min_alpha > 0 && min_alpha <= 1)) {
      throw UsageError(fmt::format("{}: the minimum alpha must be in (0, 1]", source));
    }
    o->min_alpha = min_alpha;
  } else if (n == "out") {
    o->out = AsPath(value, source, base_dir);
  } else if (n == "jobs") {
    o->jobs = CheckedInt(value, source, 1, 256);
  } else if (n == "command-timeout") {
    const double seconds = AsDouble(value, source);
    if (!(seconds >= 0) || !std::isfinite(seconds)) {
      throw UsageError(fmt::format("{}: the timeout must be >= 0 seconds", source));
    }
    o->command_timeout = seconds;
  } else if (n == "projection-metric") {
    const std::string metric = AsString(value, source);
    if (metric != "none" && !metrics::ParseMetric(metric)) {
      throw UsageError(fmt::format("{}: unknown metric '{}'", source, metric));
    }
    o->projection_metric = metric;
  } else if (n == "report") {
    o->report = AsBool(value, source);
  } else {
    throw UsageError(fmt::format("{}: setting '{}' is not handled", source, n));  // unreachable
  }
}

namespace {

SettingValue FromToml(const toml::node& node, const std::string& source) {
  if (const auto* s = node.as_string()) return s->get();
  if (const auto* i = node.as_integer()) return i->get();
  if (const auto* d = node.as_floating_point()) return d->get();
  if (const auto* b = node.as_boolean()) return b->get();
  if (const auto* array = node.as_array()) {
    std::vector<std::string> items;
    for (const toml::node& item : *array) {
      const auto* s = item.as_string();
      if (s == nullptr) throw UsageError(source + ": expected an array of strings");
      items.push_back(s->get());
    }
    return items;
  }
  throw UsageError(source + ": unsupported value (tables and dates are not settings)");
}

SettingValue FromJson(const nlohmann::json& node, const std::string& source) {
  if (node.is_string()) return node.get<std::string>();
  if (node.is_boolean()) return node.get<bool>();
  if (node.is_number_integer()) return node.get<int64_t>();
  if (node.is_number_float()) return node.get<double>();
  if (node.is_array()) {
    std::vector<std::string> items;
    for (const auto& item : node) {
      if (!item.is_string()) throw UsageError(source + ": expected an array of strings");
      items.push_back(item.get<std::string>());
    }
    return items;
  }
  throw UsageError(source + ": unsupported value (objects and null are not settings)");
}

}  // namespace

void LoadConfigFile(const fs::path& file, EvaluateOptions* options,
                    const std::vector<std::string>& extra_tables, nlohmann::json* tables) {
  LoadConfigText(ReadFileToString(file), file, options, extra_tables, tables);
}

void LoadConfigText(std::string_view text, const fs::path& file, EvaluateOptions* options,
                    const std::vector<std::string>& extra_tables, nlohmann::json* tables) {
  auto is_extra = [&](const std::string& name) {
    return tables != nullptr &&
           std::find(extra_tables.begin(), extra_tables.end(), name) != extra_tables.end();
  };
  std::string extension = file.extension().string();
  for (char& c : extension) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  REPHOTO_CHECK(extension == ".toml" || extension == ".json", "{}: config files are .toml or .json",
                file.string());
  const fs::path base_dir = fs::absolute(file).parent_path();
  std::vector<std::pair<std::string, SettingValue>> entries;
  if (extension == ".toml") {
    toml::table table;
    try {
      table = toml::parse(text, file.string());
    } catch (const toml::parse_error& e) {
      ThrowError("{}:{}:{}: {}", file.string(), e.source().begin.line, e.source().begin.column,
                 e.description());
    }
    for (const auto& [key, node] : table) {
      const std::string name(key.str());
      const std::string source = fmt::format("{}: key '{}'", file.string(), name);
      if (is_extra(name)) {
        const auto* sub = node.as_table();
        if (sub == nullptr)
          throw UsageError(fmt::format("{}: expected a table [{}]", source, name));
        std::ostringstream json;
        json << toml::json_formatter{*sub};
        (*tables)[name] = nlohmann::json::parse(json.str());
        continue;
      }
      if (FindSetting(name) == nullptr) {
        throw UsageError(
            fmt::format("{}: unknown key '{}' (known: {})", file.string(), name, KnownNames()));
      }
      entries.emplace_back(name, FromToml(node, source));
    }
  } else {
    nlohmann::json json;
    try {
      json = nlohmann::json::parse(text);
    } catch (const nlohmann::json::exception& e) {
      // parse_error, and out_of_range for numbers beyond double ("1e999").
      ThrowError("{}: invalid JSON: {}", file.string(), e.what());
    }
    REPHOTO_CHECK(json.is_object(), "{}: expected a JSON object of settings", file.string());
    for (const auto& [name, node] : json.items()) {
      const std::string source = fmt::format("{}: key '{}'", file.string(), name);
      if (is_extra(name)) {
        if (!node.is_object()) throw UsageError(fmt::format("{}: expected an object", source));
        (*tables)[name] = node;
        continue;
      }
      if (FindSetting(name) == nullptr) {
        throw UsageError(
            fmt::format("{}: unknown key '{}' (known: {})", file.string(), name, KnownNames()));
      }
      entries.emplace_back(name, FromJson(node, source));
    }
  }
  bool has_reconstruct = false;
  for (const auto& [name, value] : entries) {
    has_reconstruct |= Canonical(name) == "reconstruct";
  }
  for (const auto& [name, value] : entries) {
    const std::string source = fmt::format("{}: key '{}'", file.string(), name);
    ApplySetting(options, name, value, source, base_dir);
    // A model file is relative to the config file; with a reconstruct command it is a path
    // inside {out} and stays as written.
    if (Canonical(name) == "model" && !has_reconstruct && options->model.is_relative()) {
      options->model = base_dir / options->model;
    }
  }
  options->config_file = file;
}

Json SettingsJson(const EvaluateOptions& o) {
  Json j;
  j["scene"] = o.scene.string();
  j["format"] = o.format;
  j["image-root"] = o.image_root.string();
  j["scheme"] = o.scheme;
  j["model"] = o.model.string();
  j["reconstruct"] = o.reconstruct;
  j["render"] = o.render;
  j["representation"] = std::string(render::RepresentationName(o.representation));
  j["depth-maps"] = o.depth_maps.string();
  j["colorize"] = o.colorize;
  j["texture"] = o.texture;
  j["train-count"] = o.train_count;
  j["train-seed"] = o.train_seed;
  j["train-short-side"] = o.train_short_side;
  j["texture-noise"] = o.degrade.texture_noise;
  j["geometry-noise"] = o.degrade.geometry_noise;
  j["simplify"] = o.degrade.simplify;
  j["defect-seed"] = o.degrade.seed;
  j["eval-short-side"] = o.eval_short_side;
  Json metric_names = Json::array();
  for (metrics::Metric m : o.metrics) metric_names.push_back(metrics::MetricName(m));
  j["metrics"] = metric_names;
  j["compat"] = o.compat ? std::string(metrics::CompatPresetName(*o.compat)) : std::string();
  Json compat_names = Json::array();
  for (metrics::Metric m : CompatMetrics(o)) compat_names.push_back(metrics::MetricName(m));
  j["compat-metrics"] = compat_names;
  j["lpips-weights"] = o.lpips_weights.string();
  j["lpips-net"] = std::string(lpips::LpipsNetName(o.lpips_net));
  j["window"] = o.metric_options.window;
  j["ssim-mode"] = o.metric_options.ssim_gaussian ? "gaussian" : "skimage";
  j["dark"] = o.exposure.dark_threshold;
  j["saturated"] = o.exposure.saturated_threshold;
  j["photo-masks"] = o.photo_masks.string();
  j["resize"] = o.resize;
  j["error-images"] = o.error_images;
  Json error_image_names = Json::array();
  for (metrics::Metric m : ErrorImageMetrics(o))
    error_image_names.push_back(metrics::MetricName(m));
  j["error-image-metrics"] = ErrorImageMetrics(o).empty() ? Json("all") : error_image_names;
  j["depth-images"] = o.depth_images;
  j["spp"] = o.samples_per_pixel;
  j["backfaces"] = o.backfaces;
  j["point-radius"] = o.point_radius;
  j["point-neighbors"] = o.point_neighbors;
  j["gaussian-mode"] = std::string(GaussianModeName(o.gaussian_mode));
  j["background"] =
      fmt::format("{:g},{:g},{:g}", o.background[0], o.background[1], o.background[2]);
  j["min-alpha"] = o.min_alpha;
  j["out"] = o.out.string();
  j["jobs"] = o.jobs;
  j["command-timeout"] = o.command_timeout;
  j["projection-metric"] = o.projection_metric;
  j["report"] = o.report;
  return j;
}

}  // namespace rephoto::eval
