#include "rephoto/eval/keys.h"

#include <algorithm>

#include "rephoto/compare/compare.h"
#include "rephoto/eval/state.h"

namespace rephoto::eval {

void AddCamera(Hasher& h, const camera::Camera& camera) {
  h.AddInt(static_cast<int64_t>(camera.model)).AddInt(camera.width).AddInt(camera.height);
  h.AddInt(static_cast<int64_t>(camera.params.size()));
  for (double p : camera.params) h.AddDouble(p);
}

void AddPose(Hasher& h, const camera::Pose& pose) {
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) h.AddDouble(pose.rotation(r, c));
    h.AddDouble(pose.translation[r]);
  }
}

std::string TrainKey(const scene::Scene& train, int short_side) {
  Hasher h;
  h.Add(kKeyVersion).Add("train").AddInt(short_side);
  for (const scene::View& view : train.views) {
    h.Add(view.name);
    AddCamera(h, train.CameraOf(view));
    AddPose(h, view.cam_from_world);
  }
  h.AddInt(static_cast<int64_t>(train.points.size()));
  for (const scene::Point3D& point : train.points) {
    for (int i = 0; i < 3; ++i) h.AddDouble(point.position[i]).AddInt(point.color[i]);
    h.AddInt(static_cast<int64_t>(point.track.size()));
    for (const scene::Observation& obs : point.track) {
      h.AddInt(obs.view_index).AddDouble(obs.pixel.x()).AddDouble(obs.pixel.y());
    }
  }
  return h.Hex();
}

std::string CompareSettingsKey(const EvaluateOptions& o) {
  Hasher h;
  h.Add("compare");
  for (metrics::Metric m : o.metrics) h.Add(metrics::MetricName(m));
  const metrics::MetricOptions& mo = o.metric_options;
  h.AddInt(mo.window).AddInt(mo.ssim_gaussian).AddInt(mo.ssim_window).AddDouble(mo.ssim_sigma);
  h.AddDouble(mo.ncc_flat_threshold).AddInt(mo.icid_window).AddDouble(mo.icid_sigma);
  h.AddDouble(o.exposure.dark_threshold).AddDouble(o.exposure.saturated_threshold);
  h.AddInt(o.resize).AddInt(o.error_images).AddInt(o.eval_short_side);
  if (std::find(o.metrics.begin(), o.metrics.end(), metrics::Metric::kLpips) != o.metrics.end()) {
    // (only then: the keys of runs without lpips stay as they were)
    h.Add("lpips").Add(lpips::LpipsNetName(o.lpips_net));
    h.Add(lpips::LpipsWeightsDirectory(o.lpips_weights).string());
  }
  const std::vector<metrics::Metric> error_images = ErrorImageMetrics(o);
  if (!error_images.empty()) {  // (all metrics keeps the keys of runs made before the option)
    h.Add("error-image-metrics");
    for (metrics::Metric m : error_images) h.Add(metrics::MetricName(m));
  }
  if (o.compat) {  // (absent otherwise: the keys of runs made before --compat stay valid)
    h.Add("compat").Add(metrics::CompatPresetName(*o.compat));
    for (metrics::Metric m : CompatMetrics(o)) h.Add(metrics::MetricName(m));
    for (float c : o.background) h.AddDouble(c);
  }
  h.Add(compare::ToolVersion());
  return h.Hex();
}

std::string RenderSettingsKey(const EvaluateOptions& o) {
  Hasher h;
  h.Add("render").Add(render::RepresentationName(o.representation)).AddInt(o.samples_per_pixel).AddInt(o.backfaces);
  h.AddDouble(o.point_radius).AddInt(o.point_neighbors);
  return h.Hex();
}

std::string ModelFileKey(FileHashCache& hashes, const std::filesystem::path& path,
                         const mesh::Mesh& mesh) {
  Hasher h;
  h.Add("model").Add(hashes.Hash(path));
  for (const mesh::Material& material : mesh.materials) {
    h.Add(material.name);
    for (int c = 0; c < 3; ++c) h.AddDouble(material.diffuse[c]);
    h.Add(material.diffuse_texture.empty() ? std::string() : hashes.Hash(material.diffuse_texture));
  }
  return h.Hex();
}

std::string DerivedModelKey(const EvaluateOptions& o, const std::string& model_key,
                            const std::string& train_key) {
  Hasher h;
  h.Add(kKeyVersion).Add("colorize").Add(model_key);
  if (o.colorize) h.Add(train_key);
  if (o.texture) h.Add("texture").Add(train_key);
  if (HasDefects(o.degrade)) {
    h.Add("degrade")
        .AddDouble(o.degrade.texture_noise)
        .AddDouble(o.degrade.geometry_noise)
        .AddDouble(o.degrade.simplify)
        .AddDouble(o.degrade.noise_frequency)
        .AddInt(static_cast<int64_t>(o.degrade.seed));
  }
  return h.Hex();
}

std::string GaussianModelKey(const EvaluateOptions& o, const std::string& file_hash) {
  return Hasher()
      .Add(kKeyVersion)
      .Add("gaussians")
      .Add(file_hash)
      .Add(GaussianModeName(o.gaussian_mode))
      .AddDouble(o.background[0])
      .AddDouble(o.background[1])
      .AddDouble(o.background[2])
      .AddDouble(o.min_alpha)
      .Hex();
}

std::string RenderKey(const std::string& base_key, const TestView& test) {
  Hasher h;
  h.Add(kKeyVersion).Add("render").Add(base_key).Add(test.stem);
  AddCamera(h, test.camera);
  AddPose(h, test.pose);
  return h.Hex();
}

std::string ViewKey(const TestView& test, const std::string& base_key,
                    const std::string& render_hash, const std::string& compare_settings_key) {
  Hasher h;
  h.Add(kKeyVersion).Add("view").Add(base_key).Add(render_hash).Add(test.stem).Add(test.name);
  AddCamera(h, test.camera);
  AddPose(h, test.pose);
  h.Add(test.photo_hash).Add(test.mask_hash).Add(compare_settings_key);
  return h.Hex();
}

}  // namespace rephoto::eval
