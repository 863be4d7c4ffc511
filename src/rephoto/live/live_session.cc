#include "rephoto/live/live_session.h"

#include <fcntl.h>
#include <openssl/evp.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <fstream>
#include <map>
#include <sstream>

#include "rephoto/compare/compare.h"
#include "rephoto/core/colormap.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/core/progress.h"
#include "rephoto/ibr/depth_map_io.h"
#include "rephoto/ibr/image_based_renderer.h"
#include "rephoto/io/image_io.h"
#include "rephoto/live/sidecar.h"
#include "rephoto/project/project.h"
#include "rephoto/render/render_model.h"
#include "rephoto/run/run_folder.h"
#include "rephoto/scene/colmap.h"
#include "rephoto/scene/image_name.h"

namespace rephoto::live {
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

void LiveOptions::Check() const {
  REPHOTO_CHECK_USAGE(!watch.empty() && !out.empty(), "live: --watch and --out are required");
  REPHOTO_CHECK_USAGE(suggestions >= 1 && candidates >= suggestions,
                      "live: --suggestions must be >= 1 and <= --candidates");
  REPHOTO_CHECK_USAGE(predict_width >= 16 && depth_width >= 16 && depth_planes >= 2,
                      "live: --predict-width/--depth-width must be >= 16, planes >= 2");
  REPHOTO_CHECK_USAGE(neighbors >= 1, "live: --neighbors must be >= 1");
  REPHOTO_CHECK_USAGE(blur_ratio >= 0 && blur_ratio < 1, "live: --blur-ratio must be in [0, 1)");
  REPHOTO_CHECK_USAGE(sidecar_wait >= 0, "live: --sidecar-wait must be >= 0");
  REPHOTO_CHECK_USAGE(log_compaction_slack >= 0, "live: log_compaction_slack must be >= 0");
  const fs::path w = fs::weakly_canonical(watch), o = fs::weakly_canonical(out);
  REPHOTO_CHECK_USAGE(w != o && std::mismatch(w.begin(), w.end(), o.begin(), o.end()).first != w.end(),
                      "live: --out must not be inside --watch");
}

ibr::ImageBasedOptions PredictionIbrOptions() {
  // Measured on the closed loop at 320 x 240 (docs/live.md): a 5 % depth tolerance and a proxy
  // grid every 2 pixels raised the held-out completeness of the ring sequence after 8 photos
  // from 0.14 (the defaults 2 %, 4 px, min NCC 0.5) to 0.38 with plane-sweep min NCC 0.3.
  ibr::ImageBasedOptions o;
  o.depth_tolerance = 0.05;
  o.proxy_grid_spacing = 2;
  // Measured on the closed loop at 320-640 wide (docs/live.md, seventh stop): a photo that sees
  // the floor at a grazing angle sampled the background beyond its far edge into the views
  // beside it; 0.5 radians per doubling of the pixel footprint lowered the suggested sequence's
  // held-out error at every size (at 560: 0.1 and 2 less, 1 about as much); neutral on real
  // photos (fox, temple).
  o.resolution_penalty = 0.5;
  return o;
}

namespace {

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

std::string Sha256(const std::string& bytes) {
  unsigned char digest[EVP_MAX_MD_SIZE];
  unsigned int len = 0;
  EVP_Digest(bytes.data(), bytes.size(), digest, &len, EVP_sha256(), nullptr);
  static const char* hex = "0123456789abcdef";
  std::string s;
  for (unsigned int i = 0; i < len; ++i) {
    s += hex[digest[i] >> 4];
    s += hex[digest[i] & 15];
  }
  return s;
}

// A depth map times s (NaN, unknown, stays NaN).
Image ScaledDepth(Image depth, double s) {
  if (s == 1) return depth;
  const float f = static_cast<float>(s);
  for (size_t px = 0; px < depth.pixel_count() * depth.channels(); ++px) depth.data()[px] *= f;
  return depth;
}

// Area-average reduction to width w (aspect kept), any channel count.
Image Reduce(const Image& src, int w) {
  if (src.width() <= w) return src;
  const int h = std::max(1, static_cast<int>(std::lround(double(src.height()) * w / src.width())));
  Image out(w, h, src.channels(), 0.f);
  const double sx = double(src.width()) / w, sy = double(src.height()) / h;
  for (int y = 0; y < h; ++y) {
    const int y0 = static_cast<int>(y * sy), y1 = std::max(y0 + 1, static_cast<int>((y + 1) * sy));
    for (int x = 0; x < w; ++x) {
      const int x0 = static_cast<int>(x * sx), x1 = std::max(x0 + 1, static_cast<int>((x + 1) * sx));
      for (int c = 0; c < src.channels(); ++c) {
        double s = 0;
        for (int yy = y0; yy < y1; ++yy)
          for (int xx = x0; xx < x1; ++xx) s += src.at(xx, yy, c);
        out.at(x, y, c) = static_cast<float>(s / ((y1 - y0) * (x1 - x0)));
      }
    }
  }
  return out;
}

// Variance of the 4-neighbour Laplacian of the grey image at 256 pixels wide.
double Sharpness(const Image& photo) {
  const Image small = Reduce(photo, 256);
  const int w = small.width(), h = small.height(), ch = small.channels();
  auto grey = [&](int x, int y) {
    if (ch >= 3)
      return 0.299 * small.at(x, y, 0) + 0.587 * small.at(x, y, 1) + 0.114 * small.at(x, y, 2);
    return double(small.at(x, y, 0));
  };
  double s = 0, s2 = 0;
  size_t n = 0;
  for (int y = 1; y + 1 < h; ++y) {
    for (int x = 1; x + 1 < w; ++x) {
      const double l = grey(x - 1, y) + grey(x + 1, y) + grey(x, y - 1) + grey(x, y + 1) - 4 * grey(x, y);
      s += l;
      s2 += l * l;
      ++n;
    }
  }
  return n ? s2 / n - (s / n) * (s / n) : 0.0;
}

nlohmann::json Number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

bool FinalStatus(const std::string& s) { return s != "waiting"; }

}  // namespace

struct Photo {
  std::string name;
  std::string status;  // registered, not_an_image, unreadable, duplicate, ...
  std::string message;
  std::string sha256;
  int64_t arrival = 0;
  double completeness = 0;
  double error = std::numeric_limits<double>::quiet_NaN();
  double sharpness = 0;
  bool has_pose = false;
  std::string pose_source;  // "sidecar" or "colmap"
  camera::Camera camera;
  camera::Pose pose;
  bool has_depth = false;
  // Angle (degrees) between its viewing direction and its nearest other photo's when its
  // plane-sweep depth was estimated (the depth is estimated again when a photo at under half
  // that angle arrives); 0 = unknown.
  double depth_gap = 0;
  // Its pose was refined by the registration engine after the depth map was estimated
  // (live_session.h): the map (scaled with the frame) is used until it is estimated again.
  bool depth_stale = false;
  // depth/<name>.bin stays as estimated; times depth_scale it is the depth in the current frame
  // (the scale of the similarities bundle adjustments moved the frame by since; 1 after every
  // estimation). A record without it (older runs rewrote the file) means 1.
  double depth_scale = 1;
  bool has_error_image = false;
  std::map<std::string, double> seconds;
  std::string time;  // UTC ISO time of the record

  nlohmann::json Json() const {
    nlohmann::json j = {{"name", name},
                        {"status", status},
                        {"message", message},
                        {"sha256", sha256},
                        {"arrival", arrival},
                        {"completeness", Number(completeness)},
                        {"error", Number(error)},
                        {"sharpness", Number(sharpness)},
                        {"seconds", seconds},
                        {"time", time},
                        {"has_depth", has_depth},
                        {"depth_gap", depth_gap},
                        {"depth_stale", depth_stale},
                        {"depth_scale", depth_scale},
                        {"has_error_image", has_error_image}};
    if (has_pose) {
      j.update(SidecarJson(camera, pose));
      j["pose_source"] = pose_source;
    }
    return j;
  }
  static Photo FromJson(const nlohmann::json& j) {
    Photo p;
    p.name = j.at("name").get<std::string>();
    p.status = j.at("status").get<std::string>();
    p.message = j.value("message", "");
    p.sha256 = j.value("sha256", "");
    p.arrival = j.value("arrival", int64_t{0});
    p.completeness = j["completeness"].is_number() ? j["completeness"].get<double>() : 0.0;
    p.error = j["error"].is_number() ? j["error"].get<double>() : std::nan("");
    p.sharpness = j["sharpness"].is_number() ? j["sharpness"].get<double>() : 0.0;
    if (j.contains("seconds")) p.seconds = j["seconds"].get<std::map<std::string, double>>();
    p.time = j.value("time", "");
    p.has_depth = j.value("has_depth", false);
    p.depth_gap = j["depth_gap"].is_number() ? j["depth_gap"].get<double>() : 0.0;
    p.depth_stale = j.value("depth_stale", false);
    p.depth_scale = j["depth_scale"].is_number() ? j["depth_scale"].get<double>() : 1.0;
    REPHOTO_CHECK(std::isfinite(p.depth_scale) && p.depth_scale > 0,
                  "live.jsonl: {}: depth_scale must be a positive number", p.name);
    p.has_error_image = j.value("has_error_image", false);
    if (j.contains("qvec")) {
      const PoseSidecar s = ParseSidecar(j.dump(), "live.jsonl: " + p.name);
      p.camera = s.camera;
      p.pose = s.cam_from_world;
      p.has_pose = true;
      p.pose_source = j.value("pose_source", "sidecar");
    }
    return p;
  }
};

struct Waiting {
  std::string name;
  Clock::time_point since;
};

struct LiveSession::State {
  LiveOptions options;
  run::RunFolder folder;
  mutable std::mutex mutex;  // guards photos/api/version for the HTTP threads
  std::vector<Photo> photos;                 // one per name, in arrival order
  std::map<std::string, size_t> by_name;     // name -> index into photos
  // name -> plane-sweep depth map (shared with the predictions that use it: no copy per use)
  std::map<std::string, std::shared_ptr<const Image>> depth_cache;
  // The proxy of the last update (the envelope plus the support plane, live_model.h) ready for
  // ray casting: every photo's live depth map (LiveDepth). Null until a depth point exists.
  std::unique_ptr<render::RenderModel> proxy_model;
  uint64_t proxy_id = 0;
  struct LiveDepthEntry {
    uint64_t proxy_id = 0;
    std::shared_ptr<const Image> depth;
  };
  std::map<std::string, LiveDepthEntry> live_depth;  // name -> live depth map (cache)
  std::vector<Waiting> waiting;
  nlohmann::json suggestions = nlohmann::json::array();
  nlohmann::json model = nlohmann::json::object();
  uint64_t version = 0;
  int64_t next_arrival = 0;
  size_t log_records = 0;  // complete lines in live.jsonl
  nlohmann::json api;

  fs::path Dir(const std::string& sub) const { return options.out / sub; }

  static std::string Now() {
    const std::time_t t = std::time(nullptr);
    char buf[32];
    std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
    return buf;
  }

  // One line of live.jsonl per record.
  static std::string RecordLines(const std::vector<Photo>& records) {
    std::string text;
    for (const Photo& p : records)
      text += p.Json().dump(-1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
    return text;
  }

  // `text` into `path` opened with `flags`, in one write, on disk (fsync) before it returns.
  static void WriteSynced(const fs::path& path, int flags, const std::string& text) {
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC | flags, 0644);
    REPHOTO_CHECK(fd >= 0, "{}: cannot open for writing", path.string());
    const ssize_t n = ::write(fd, text.data(), text.size());
    const bool synced = ::fsync(fd) == 0;
    ::close(fd);
    REPHOTO_CHECK(n == static_cast<ssize_t>(text.size()) && synced, "{}: write failed",
                  path.string());
  }

  // Appends the records in one write and one fsync.
  void Append(const std::vector<Photo>& records) {
    WriteSynced(options.out / "live.jsonl", O_APPEND, RecordLines(records));
    log_records += records.size();
  }

  // live.jsonl rewritten with the current record of each name, in arrival order (`photos`),
  // when it has grown past the bound of LiveOptions::log_compaction_slack. The new content is
  // on disk (fsync) before it replaces the old, so a kill or a power cut at any point leaves
  // one of the two complete logs.
  void CompactLogIfLong() {
    std::string text;
    size_t count = 0;
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (log_records <= photos.size() + static_cast<size_t>(options.log_compaction_slack))
        return;
      text = RecordLines(photos);
      count = photos.size();
    }
    const fs::path path = options.out / "live.jsonl";
    const fs::path tmp = options.out / "live.jsonl.compact";
    WriteSynced(tmp, O_TRUNC, text);
    std::error_code ec;
    fs::rename(tmp, path, ec);
    REPHOTO_CHECK(!ec, "{}: cannot replace with the compacted log: {}", path.string(), ec.message());
    const int dir = ::open(options.out.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dir >= 0) {
      ::fsync(dir);
      ::close(dir);
    }
    log_records = count;
  }

  void Put(Photo p) { Put(std::vector<Photo>{std::move(p)}); }

  // Several records (e.g. the photos a bundle adjustment moved) in one append.
  void Put(std::vector<Photo> records) {
    if (records.empty()) return;
    const std::string now = Now();
    for (Photo& p : records) p.time = now;
    Append(records);
    {
      std::lock_guard<std::mutex> lock(mutex);
      for (Photo& p : records) {
        auto it = by_name.find(p.name);
        if (it == by_name.end()) {
          by_name[p.name] = photos.size();
          photos.push_back(std::move(p));
        } else {
          photos[it->second] = std::move(p);
        }
      }
    }
    CompactLogIfLong();
  }

  void Resume() {
    // The last suggestions and model figures (rewritten with the next photo).
    try {
      if (fs::exists(Dir("suggestions") / "suggestions.json"))
        suggestions = nlohmann::json::parse(ReadFileToString(Dir("suggestions") / "suggestions.json"));
      if (fs::exists(options.out / "model.json"))
        model = nlohmann::json::parse(ReadFileToString(options.out / "model.json"));
    } catch (const std::exception& e) {
      LogWarning(fmt::format("{}: previous suggestions not restored: {}", options.out.string(), e.what()));
    }
    const fs::path path = options.out / "live.jsonl";
    if (!fs::exists(path)) return;
    const std::string text = ReadFileToString(path);
    size_t start = 0, line_no = 0;
    while (start < text.size()) {
      const size_t end = text.find('\n', start);
      if (end == std::string::npos) break;  // a torn last line (killed mid-write): ignored
      ++line_no;
      const std::string line = text.substr(start, end - start);
      start = end + 1;
      try {
        Photo p = Photo::FromJson(nlohmann::json::parse(line));
        auto it = by_name.find(p.name);
        next_arrival = std::max(next_arrival, p.arrival + 1);
        if (it == by_name.end()) {
          by_name[p.name] = photos.size();
          photos.push_back(std::move(p));
        } else {
          photos[it->second] = std::move(p);
        }
      } catch (const std::exception& e) {
        LogWarning(fmt::format("{}:{}: record ignored: {}", path.string(), line_no, e.what()));
      }
    }
    log_records = line_no;
    CompactLogIfLong();
    for (Photo& p : photos) {
      if (p.status == "unregistered") {
        const auto it = p.seconds.find("register");
        unplaced.push_back({p.name, p.arrival, p.sha256, p.sharpness,
                            it == p.seconds.end() ? 0.0 : it->second});
      }
      if (p.status == "registered" && p.has_depth) {
        try {
          depth_cache[p.name] = std::make_shared<const Image>(
              ScaledDepth(ibr::ReadDepthMap(Dir("depth") / (p.name + ".bin")), p.depth_scale));
        } catch (const std::exception& e) {
          LogWarning(e.what());
          p.has_depth = false;
        }
      }
    }
    try {
      TakeRefinedPoses();  // refinements after the last record (a kill -9 mid-photo)
    } catch (const std::exception& e) {
      LogWarning(fmt::format("resume: refined poses not taken over: {}", e.what()));
    }
    try {
      BuildModel();
    } catch (const std::exception& e) {
      LogWarning(fmt::format("resume: model not rebuilt: {}", e.what()));
    }
  }

  std::vector<size_t> Registered() const {
    std::vector<size_t> r;
    for (size_t i = 0; i < photos.size(); ++i)
      if (photos[i].status == "registered") r.push_back(i);
    return r;
  }

  // Registered photos nearest to a pose: centre distance (relative to the median distance
  // between registered cameras and the pose) plus the angle between viewing directions.
  std::vector<size_t> Nearest(const camera::Pose& pose, size_t count, bool need_depth,
                              const std::string& exclude) const {
    std::vector<std::pair<double, size_t>> ranked;
    std::vector<double> dist;
    for (size_t i : Registered()) dist.push_back((photos[i].pose.Center() - pose.Center()).norm());
    if (dist.empty()) return {};
    std::vector<double> sorted = dist;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double scale = std::max(1e-9, sorted[sorted.size() / 2]);
    size_t k = 0;
    for (size_t i : Registered()) {
      const double d = dist[k++];
      if (photos[i].name == exclude || (need_depth && !HasLiveDepth(i))) continue;
      const double angle = std::acos(std::clamp(
          photos[i].pose.ViewDirection().dot(pose.ViewDirection()), -1.0, 1.0));
      ranked.push_back({d / scale + angle, i});
    }
    std::sort(ranked.begin(), ranked.end());
    std::vector<size_t> r;
    for (size_t j = 0; j < ranked.size() && j < count; ++j) r.push_back(ranked[j].second);
    return r;
  }

  ibr::TrainingView Training(size_t i) const {
    const Photo& p = photos[i];
    return {p.name, p.camera, p.pose, options.watch / p.name,
            p.has_depth ? Dir("depth") / (p.name + ".bin") : fs::path()};
  }


  // The live depth map of photo i (see live_session.h): in an object-centred capture, the
  // proxy of the last update (envelope plus support plane, BuildModel) ray-cast at its camera
  // (pixel centres) at the plane-sweep map's size (depth_width wide without one); otherwise
  // (no proxy: a forward-facing capture, or no depth point yet) its plane-sweep depth. Null
  // when it has neither. Cached per proxy.
  std::shared_ptr<const Image> LiveDepth(size_t i) {
    const Photo& p = photos[i];
    auto plane = depth_cache.find(p.name);
    if (!proxy_model) {
      if (plane == depth_cache.end()) return nullptr;
      return plane->second;
    }
    auto cached = live_depth.find(p.name);
    if (cached != live_depth.end() && cached->second.proxy_id == proxy_id) return cached->second.depth;
    int w = std::min(options.depth_width, p.camera.width);
    int h = std::max(1, static_cast<int>(std::lround(double(p.camera.height) * w / p.camera.width)));
    if (plane != depth_cache.end()) {
      w = plane->second->width();
      h = plane->second->height();
    }
    const camera::Camera cam = p.camera.width == w ? p.camera : p.camera.Scaled(w, h);
    render::RenderOptions ro;
    ro.samples_per_pixel = 1;
    render::Rephoto r = render::RenderRephoto(*proxy_model, cam, p.pose, ro);
    auto out = std::make_shared<const Image>(std::move(r.depth));
    live_depth[p.name] = {proxy_id, out};
    return out;
  }

  // Every registered photo has a live depth map once a proxy exists; before, the ones with a
  // plane-sweep map.
  bool HasLiveDepth(size_t i) const { return proxy_model != nullptr || photos[i].has_depth; }

  // The live prediction at camera/pose: IBR from the `neighbors` registered photos nearest to
  // the pose (except `exclude`) with their live depth maps; nullopt when none has one.
  std::optional<render::Rephoto> Predict(const camera::Camera& cam, const camera::Pose& pose,
                                         const std::string& exclude) {
    std::vector<ibr::TrainingView> training;
    for (size_t i : Nearest(pose, options.neighbors, true, exclude)) {
      std::shared_ptr<const Image> d = LiveDepth(i);
      if (!d) continue;
      ibr::TrainingView t = Training(i);
      t.depth_map.clear();
      t.depth = std::move(d);
      training.push_back(std::move(t));
    }
    if (training.empty()) return std::nullopt;
    const ibr::ImageBasedRenderer r =
        ibr::ImageBasedRenderer::Ibr(std::move(training), PredictionIbrOptions());
    return r.Render(cam, pose);
  }

  // The envelope of all plane-sweep depth maps so far; its proxy is kept for LiveDepth once it
  // holds a depth point (with none it is a guess, and a guess predicts nothing) when the
  // capture is object-centred (Envelope::converging). A capture that stops converging (a
  // forward-facing part added) drops the proxy.
  Envelope BuildModel() {
    const std::vector<size_t> reg = Registered();
    REPHOTO_CHECK(!reg.empty(), "model: no registered photo");
    std::vector<camera::Pose> poses;
    std::vector<EnvelopeInput> inputs;
    for (size_t i : reg) {
      poses.push_back(photos[i].pose);
      auto it = depth_cache.find(photos[i].name);
      if (it == depth_cache.end()) continue;
      inputs.push_back({photos[i].camera.Scaled(it->second->width(), it->second->height()),
                        photos[i].pose, it->second.get()});
    }
    Envelope env = BuildEnvelope(poses, inputs, options.envelope);
    // The proxy models an object-centred capture (the photos' axes converge on the object);
    // a forward-facing capture (nearly parallel axes, e.g. fern) keeps plane-sweep depth.
    if (env.converging && env.point_count > 0 && env.ObservedFraction() > 0) {
      // The proxy: the envelope plus the support plane's seen cells.
      mesh::Mesh proxy = env.mesh;
      const uint32_t base = static_cast<uint32_t>(proxy.positions.size());
      proxy.positions.insert(proxy.positions.end(), env.support.positions.begin(),
                             env.support.positions.end());
      for (const mesh::Triangle& t : env.support.faces)
        proxy.faces.push_back({t[0] + base, t[1] + base, t[2] + base});
      proxy_model = std::make_unique<render::RenderModel>(proxy);
      ++proxy_id;
    } else {
      proxy_model.reset();
    }
    return env;
  }

  camera::Camera PredictCamera(const camera::Camera& cam) const {
    if (cam.width <= options.predict_width) return cam;
    const int h = std::max(1, static_cast<int>(std::lround(double(cam.height) * options.predict_width / cam.width)));
    return cam.Scaled(options.predict_width, h);
  }

  void WriteRgbaPng(const fs::path& path, Image image) {
    WriteFileAtomically(path, [&](const fs::path& tmp) { io::WritePng(tmp, image); });
  }

  // Depth maps for the photos `targets` (registered), each against its nearest photos.
  void EstimateDepth(const std::vector<size_t>& targets) {
    for (size_t t : targets) {
      const std::vector<size_t> near = Nearest(photos[t].pose, 8, false, photos[t].name);
      if (near.empty()) continue;
      std::vector<ibr::TrainingView> views{Training(t)};
      for (size_t i : near) views.push_back(Training(i));
      std::vector<bool> estimate(views.size(), false);
      estimate[0] = true;
      ibr::ImageBasedOptions o;
      o.plane_sweep.max_width = options.depth_width;
      o.plane_sweep.num_planes = options.depth_planes;
      o.plane_sweep.min_ncc = 0.3;
      o.sweep_min_consistent = 0;  // one view estimated at a time; IBR's fusion checks views
      std::vector<Image> depths = ibr::EstimateDepthMaps(views, estimate, o);
      Image& d = depths[0];
      size_t finite = 0;
      for (size_t p = 0; p < d.pixel_count(); ++p) finite += std::isfinite(d.data()[p]);
      if (finite == 0) continue;  // no neighbour at a usable angle yet: try again later
      ibr::WriteColmapDepthMap(Dir("depth") / (photos[t].name + ".bin"), d);
      depth_cache[photos[t].name] = std::make_shared<const Image>(std::move(d));
      live_depth.erase(photos[t].name);
      std::lock_guard<std::mutex> lock(mutex);
      photos[t].has_depth = true;
      photos[t].depth_stale = false;
      photos[t].depth_scale = 1;
      photos[t].depth_gap = NearestGap(t);
    }
  }

  // Angle (degrees) between the viewing directions of photo t and its nearest other registered
  // photo (180 when it is alone).
  double NearestGap(size_t t, size_t only = SIZE_MAX) const {
    double best = 180;
    for (size_t i : Registered()) {
      if (i == t || (only != SIZE_MAX && i != only)) continue;
      const double a = std::acos(std::clamp(
          photos[i].pose.ViewDirection().dot(photos[t].pose.ViewDirection()), -1.0, 1.0));
      best = std::min(best, a * 180 / M_PI);
    }
    return best;
  }

  // Photos whose plane-sweep depth was estimated without a close neighbour and for which the
  // new photo `added` now is one (under half their recorded gap): at most kRefreshPerPhoto,
  // the largest improvement first.
  std::vector<size_t> RefreshTargets(size_t added) const {
    std::vector<std::pair<double, size_t>> ranked;
    for (size_t i : Registered()) {
      if (i == added || !photos[i].has_depth || !(photos[i].depth_gap > 0)) continue;
      const double gap = NearestGap(i, added);
      if (gap < 0.5 * photos[i].depth_gap) ranked.push_back({gap / photos[i].depth_gap, i});
    }
    std::sort(ranked.begin(), ranked.end());
    std::vector<size_t> out;
    for (size_t k = 0; k < ranked.size() && k < kRefreshPerPhoto; ++k) out.push_back(ranked[k].second);
    return out;
  }
  static constexpr size_t kRefreshPerPhoto = 1;
  static constexpr size_t kStalePerPhoto = 4;

  void RefreshModelAndSuggestions(double* model_seconds, double* suggest_seconds) {
    const auto t0 = Clock::now();
    const std::vector<size_t> reg = Registered();
    if (reg.empty()) return;
    Envelope env = BuildModel();
    // Errors of the predictions projected onto the envelope.
    std::vector<project::ProjectView> views;
    for (size_t i : reg) {
      if (!photos[i].has_error_image) continue;
      const fs::path e = Dir("errors") / (photos[i].name + ".1-ncc.exr");
      views.push_back({photos[i].camera, photos[i].pose, e, photos[i].name, {}});
    }
    render::RenderModel surface(env.mesh);
    project::ProjectOptions po;
    po.scale_cameras = true;
    po.depth_tolerance = 0.05;  // the envelope is coarse
    po.footprint_tolerance = 4;
    project::ProjectResult projected;
    if (!views.empty()) {
      projected = project::ProjectErrors(surface, views, po);
    } else {
      projected.vertex_error.assign(env.mesh.positions.size(), std::nanf(""));
      projected.view_count.assign(env.mesh.positions.size(), 0);
      projected.low = projected.high = std::nanf("");
    }
    project::WriteProjectedPly(env.mesh, projected, options.out / "model.ply");
    // Need: 1 for unobserved directions (they stand for unseen surface), else the projected
    // error mapped to [0, 1] between its 2.5 and 97.5 % percentiles (0 without an error).
    std::vector<float> finite;
    for (float e : projected.vertex_error)
      if (std::isfinite(e)) finite.push_back(e);
    std::sort(finite.begin(), finite.end());
    const float lo = finite.empty() ? 0.f : finite[static_cast<size_t>(0.025 * (finite.size() - 1))];
    const float hi = finite.empty() ? 1.f : finite[static_cast<size_t>(0.975 * (finite.size() - 1))];
    std::vector<float> need(env.mesh.positions.size(), 0.f);
    double total = 0, well = 0;
    for (size_t v = 0; v < need.size(); ++v) {
      total += env.area[v];
      const float e = projected.vertex_error[v];
      if (!env.observed[v]) {
        need[v] = 1;
      } else if (std::isfinite(e)) {
        need[v] = kErrorNeed * (hi > lo ? std::clamp((e - lo) / (hi - lo), 0.f, 1.f) : 0.f);
        if (projected.view_count[v] >= 2 && e <= kWellCovered) well += env.area[v];
      }
    }
    *model_seconds = Seconds(t0);
    const auto t1 = Clock::now();
    // Suggestions.
    const camera::Camera& cam = photos[reg.back()].camera;
    PlanOptions plan = options.plan;
    plan.count = options.suggestions;
    plan.candidates = options.candidates;
    std::vector<camera::Pose> taken;
    for (size_t i : reg) taken.push_back(photos[i].pose);
    const std::vector<PlannedView> planned = PlanNextViews(surface, env, need, taken, cam, plan);
    nlohmann::json list = nlohmann::json::array();
    std::map<uint32_t, camera::Camera> cams{{1, cam}};
    std::vector<scene::ColmapImage> images;
    nlohmann::json frames = nlohmann::json::array();
    const Eigen::Vector3d& target = env.center;
    double unseen_total = 0;
    for (size_t v = 0; v < need.size(); ++v)
      if (need[v] >= 1) unseen_total += env.area[v];
    for (size_t k = 0; k < planned.size(); ++k) {
      const PlannedView& s = planned[k];
      const std::string name = fmt::format("suggest_{:02d}", k);
      nlohmann::json j = SidecarJson(cam, s.cam_from_world);
      const Eigen::Vector3d c = s.cam_from_world.Center();
      j["name"] = name;
      j["center"] = {c.x(), c.y(), c.z()};
      j["look_at"] = {target.x(), target.y(), target.z()};
      j["score"] = s.score;
      j["unseen_area_fraction"] = total > 0 ? s.unseen_area / total : 0.0;
      j["visible_vertices"] = s.visible_vertices;
      j["chosen_by"] = s.view_coverage ? "view_coverage" : "surface";
      j["coverage_gain_degrees"] = s.coverage_gain * 180 / M_PI;
      j["how"] = fmt::format(
          "stand at ({:.3f}, {:.3f}, {:.3f}), look at ({:.3f}, {:.3f}, {:.3f}), camera upright",
          c.x(), c.y(), c.z(), target.x(), target.y(), target.z());
      j["has_render"] = false;
      try {
        if (auto r = Predict(PredictCamera(cam), s.cam_from_world, "")) {
          WriteRgbaPng(Dir("suggestions") / (name + ".png"), r->color);
          j["has_render"] = true;
        }
      } catch (const std::exception& e) {
        LogWarning(fmt::format("{}: rephoto failed: {}", name, e.what()));
      }
      WriteTextFileAtomically(Dir("suggestions") / (name + ".json"),
                              SidecarJson(cam, s.cam_from_world).dump(2) + "\n");
      list.push_back(j);
      scene::ColmapImage im;
      im.image_id = static_cast<uint32_t>(k + 1);
      im.quaternion = s.cam_from_world.Quaternion();
      im.translation = s.cam_from_world.translation;
      im.camera_id = 1;
      im.name = name + ".png";
      images.push_back(im);
      // transforms.json: camera-to-world in the OpenGL convention (x right, y up, z back).
      Eigen::Matrix4d c2w = Eigen::Matrix4d::Identity();
      c2w.topLeftCorner<3, 3>() = s.cam_from_world.rotation.transpose();
      c2w.topRightCorner<3, 1>() = c;
      c2w.col(1) *= -1;
      c2w.col(2) *= -1;
      nlohmann::json m = nlohmann::json::array();
      for (int r = 0; r < 4; ++r) m.push_back({c2w(r, 0), c2w(r, 1), c2w(r, 2), c2w(r, 3)});
      frames.push_back({{"file_path", name + ".png"}, {"transform_matrix", m}});
    }
    {
      std::ostringstream a, b;
      scene::WriteColmapCamerasText(a, cams);
      scene::WriteColmapImagesText(b, images);
      WriteTextFileAtomically(Dir("suggestions") / "sparse" / "cameras.txt", a.str());
      WriteTextFileAtomically(Dir("suggestions") / "sparse" / "images.txt", b.str());
      WriteTextFileAtomically(Dir("suggestions") / "sparse" / "points3D.txt", "");
      const camera::Camera pin = cam;
      nlohmann::json tj = {{"w", cam.width}, {"h", cam.height},
                           {"fl_x", pin.FocalLengthX()}, {"fl_y", pin.FocalLengthY()},
                           {"cx", pin.PrincipalPointX()}, {"cy", pin.PrincipalPointY()},
                           {"camera_model", cam.IsPinhole() ? "OPENCV" : std::string(camera::CameraModelName(cam.model))},
                           {"frames", frames}};
      WriteTextFileAtomically(Dir("suggestions") / "transforms.json", tj.dump(2) + "\n");
      WriteTextFileAtomically(Dir("suggestions") / "suggestions.json", list.dump(2) + "\n");
    }
    const nlohmann::json model_json = {
        {"vertices", env.mesh.positions.size()},
        {"depth_points", env.point_count},
        {"observed_fraction", env.ObservedFraction()},
        {"unseen_fraction", 1 - env.ObservedFraction()},
        {"well_covered_fraction", total > 0 ? well / total : 0.0},
        {"well_covered_threshold", kWellCovered},
        {"unseen_area_fraction_needing_views", total > 0 ? unseen_total / total : 0.0},
        {"center", {env.center.x(), env.center.y(), env.center.z()}},
        {"support_plane", env.support.faces.empty()
                              ? nlohmann::json()
                              : nlohmann::json({env.support_plane[0], env.support_plane[1],
                                                env.support_plane[2], env.support_plane[3]})},
        {"support_plane_cells", env.support.faces.size() / 2}};
    WriteTextFileAtomically(options.out / "model.json", model_json.dump(2) + "\n");
    *suggest_seconds = Seconds(t1);
    std::lock_guard<std::mutex> lock(mutex);
    suggestions = list;
    this->model = model_json;
  }
  static constexpr double kWellCovered = 0.3;
  // Observed vertices weigh at most this much of an unseen one: unseen surface first, then
  // the highest projected error.
  static constexpr float kErrorNeed = 0.1f;

  struct Deferred {
    std::string name;
    int64_t arrival;
    std::string sha;
    double sharpness;
    double register_seconds = 0;  // spent in the engine when it arrived (features, matching)
  };
  std::vector<Deferred> deferred;  // photos the registration engine could not place yet
  // Photos it could not place (status unregistered): COLMAP's image_registrator, run for every
  // later photo, tries every unplaced image of its database again, so a photo that a later one
  // connects to the others gets placed then. Looked up after every registration.
  std::vector<Deferred> unplaced;
  std::string deferred_reason;  // why `deferred` wait (the engine's last message), for the API

  // Poses refined by the registration engine (live_session.h, "Poses refined by the engine"):
  // the engine-placed photos whose pose or camera changed take the new ones; their depth maps
  // are scaled with the frame or dropped for re-estimation (pose_update.h). Returns true when
  // something changed (the caller rebuilds the proxy).
  bool TakeRefinedPoses() {
    if (!options.registrar) return false;
    const std::vector<Registrar::Placed> placed = options.registrar->AllPlaced();
    std::map<std::string, const Registrar::Placed*> by;
    for (const Registrar::Placed& q : placed) by[q.name] = &q;
    std::vector<size_t> index;
    std::vector<camera::Pose> before, after;
    for (size_t i : Registered()) {
      if (photos[i].pose_source != "colmap") continue;
      const auto it = by.find(photos[i].name);
      if (it == by.end()) continue;
      index.push_back(i);
      before.push_back(photos[i].pose);
      after.push_back(it->second->cam_from_world);
    }
    if (index.empty()) return false;
    const std::vector<PoseChange> changes = ComparePoses(before, after, options.pose_update);
    bool any = false;
    std::vector<Photo> changed;
    for (size_t k = 0; k < index.size(); ++k) {
      Photo p = photos[index[k]];
      const Registrar::Placed& q = *by.at(p.name);
      const double pose_delta =
          std::max((q.cam_from_world.rotation - p.pose.rotation).cwiseAbs().maxCoeff(),
                   (q.cam_from_world.translation - p.pose.translation).norm() /
                       std::max(1e-12, p.pose.translation.norm() + 1));
      const double camera_delta = IntrinsicsChange(p.camera, q.camera);
      if (pose_delta < 1e-12 && camera_delta < 1e-12) continue;
      any = true;
      p.pose = q.cam_from_world;
      p.camera = q.camera;
      const auto d = depth_cache.find(p.name);
      // A stale map is still scaled and used until the join steps of the next photos estimate
      // it again (dropping it would leave the next prediction without depth after a global
      // bundle adjustment).
      if (d != depth_cache.end() &&
          (changes[k].refresh_depth || camera_delta > options.pose_update.intrinsics_fraction))
        p.depth_stale = true;
      // The file stays as estimated; the record carries the scale (no depth map rewritten per
      // photo at every bundle adjustment).
      if (d != depth_cache.end() && std::abs(changes[k].scale - 1) > 1e-12) {
        // From the file, as a restart computes it (same values).
        p.depth_scale *= changes[k].scale;
        d->second = std::make_shared<const Image>(
            ScaledDepth(ibr::ReadDepthMap(Dir("depth") / (p.name + ".bin")), p.depth_scale));
      }
      live_depth.erase(p.name);
      changed.push_back(std::move(p));
    }
    Put(std::move(changed));
    return any;
  }

  // Photos the engine deferred, then those it could not place: looked up again (each list in
  // arrival order) after a registration. An unplaced photo that is still not placed stays
  // unregistered (no new record); one that is gets predicted from the photos registered by then
  // and added, under its original arrival number.
  void RetryDeferred() {
    if (!options.registrar) return;
    std::vector<Deferred> again;
    again.swap(deferred);
    for (const Deferred& d : again) {
      const Registrar::Result r = options.registrar->Lookup(d.name);
      if (r.status == Registrar::Result::kDeferred) {
        deferred.push_back(d);
        continue;
      }
      ProcessRetried(d, r);
    }
    if (unplaced.empty()) return;
    // The engine's model read once for all of them (not one Lookup, i.e. one read, each).
    std::map<std::string, Registrar::Placed> placed;
    for (Registrar::Placed& q : options.registrar->AllPlaced()) placed[q.name] = std::move(q);
    again.clear();
    again.swap(unplaced);
    for (const Deferred& d : again) {
      const auto it = placed.find(d.name);
      if (it == placed.end()) {
        unplaced.push_back(d);
        continue;
      }
      Registrar::Result r;
      r.status = Registrar::Result::kRegistered;
      r.camera = it->second.camera;
      r.cam_from_world = it->second.cam_from_world;
      LogInfo(fmt::format("{}: placed by COLMAP after later photos", d.name));
      ProcessRetried(d, r);
    }
  }

  void ProcessRetried(const Deferred& d, const Registrar::Result& r) {
    try {
      const Image photo = io::ReadImage(options.watch / d.name);
      Process(d.name, d.arrival, d.sha, photo, d.sharpness, &r, d.register_seconds);
    } catch (const Error& e) {
      Photo p;
      p.name = d.name;
      p.arrival = d.arrival;
      p.sha256 = d.sha;
      p.status = "failed";
      p.message = e.what();
      Put(p);
    }
  }

  // `preset`: the engine's answer for a photo it deferred or could not place before, which took
  // `earlier_seconds` in the engine then (counted in its register seconds).
  void Process(const std::string& name, int64_t arrival, const std::string& sha,
               const Image& photo, double sharpness, const Registrar::Result* preset = nullptr,
               double earlier_seconds = 0) {
    Photo p;
    p.name = name;
    p.sha256 = sha;
    p.arrival = arrival;
    p.sharpness = sharpness;
    const auto t0 = Clock::now();
    // Pose.
    const fs::path sidecar = options.watch / (fs::path(name).stem().string() + ".json");
    std::error_code ec;
    if (fs::is_regular_file(sidecar, ec)) {
      try {
        const PoseSidecar s = ParseSidecar(ReadFileToString(sidecar), sidecar.filename().string());
        const double a = double(s.camera.width) / s.camera.height,
                     b = double(photo.width()) / photo.height();
        REPHOTO_CHECK(std::abs(a / b - 1) < 0.01, "{}: camera is {}x{} but the photo is {}x{}",
                      sidecar.filename().string(), s.camera.width, s.camera.height,
                      photo.width(), photo.height());
        p.camera = s.camera.width == photo.width() ? s.camera
                                                     : s.camera.Scaled(photo.width(), photo.height());
        p.pose = s.cam_from_world;
        p.has_pose = true;
        p.pose_source = "sidecar";
      } catch (const std::exception& e) {
        p.status = "bad_sidecar";
        p.message = e.what();
        Put(p);
        return;
      }
    } else if (options.registrar) {
      Registrar::Result r = preset ? *preset : options.registrar->Register(options.watch / name);
      // The engine may have refined the earlier photos' poses (bundle adjustment), also in a
      // call that could not place this photo: take them over before this photo is predicted
      // from them, in the frame its own pose is in.
      try {
        if (TakeRefinedPoses()) BuildModel();
      } catch (const std::exception& e) {
        LogWarning(fmt::format("{}: refined poses not taken over: {}", name, e.what()));
      }
      if (r.status == Registrar::Result::kDeferred) {
        deferred.push_back({name, arrival, sha, sharpness, Seconds(t0) + earlier_seconds});
        // Why they wait (the page shows it): the engine's last word, e.g. COLMAP's failed
        // initial reconstruction, else the photos it waits for.
        deferred_reason =
            r.message.empty()
                ? fmt::format("the registration engine waits for more photos ({} so far)",
                              deferred.size())
                : fmt::format("{} photos wait for the registration engine: {}", deferred.size(),
                              r.message);
        return;
      }
      if (r.status != Registrar::Result::kRegistered) {
        p.status = "unregistered";
        p.message = r.message.empty() ? "the registration engine could not place it" : r.message;
        p.seconds["register"] = Seconds(t0) + earlier_seconds;
        Put(p);
        unplaced.push_back({name, arrival, sha, sharpness, p.seconds["register"]});
        return;
      }
      p.camera = r.camera;
      p.pose = r.cam_from_world;
      p.has_pose = true;
      p.pose_source = "colmap";
    }
    p.seconds["register"] = Seconds(t0) + earlier_seconds;
    // Prediction from the photos before it.
    const auto t1 = Clock::now();
    const camera::Camera pc = PredictCamera(p.camera);
    Image small = Reduce(photo, pc.width);
    if (small.height() != pc.height) small = Reduce(photo, pc.width);  // same rounding
    WriteRgbaPng(Dir("photos") / (name + ".png"), small);
    std::optional<render::Rephoto> rendered;
    try {
      rendered = Predict(pc, p.pose, name);
    } catch (const std::exception& e) {
      p.message = fmt::format("prediction failed: {}", e.what());
    }
    if (rendered) {
      compare::CompareOptions co;
      co.metrics = {metrics::Metric::kOneMinusNcc};
      compare::CompareWorkspace ws;
      std::vector<Image> errors;
      const compare::ImageResult r =
          compare::CompareInMemory(co, small, rendered->color, nullptr, nullptr, &errors, &ws);
      p.completeness = std::isfinite(r.completeness.value) ? r.completeness.value : 0.0;
      p.error = r.metrics[0].mean;
      WriteRgbaPng(Dir("predictions") / (name + ".png"), rendered->color);
      const Image& e = errors[0];
      WriteFileAtomically(Dir("errors") / (name + ".1-ncc.exr"),
                          [&](const fs::path& tmp) { io::WriteExr(tmp, e); });
      std::vector<uint8_t> rgba;
      const auto [lo, hi] = compare::ErrorColourRange(metrics::Metric::kOneMinusNcc);
      compare::ColourErrorImage(e, lo, hi, &rgba);
      WriteFileAtomically(Dir("errors") / (name + ".png"), [&](const fs::path& tmp) {
        io::WritePng8(tmp, rgba, e.width(), e.height(), 4);
      });
      p.has_error_image = true;
    }
    p.seconds["predict"] = Seconds(t1);
    // Join: depth of this photo and of registered photos without depth.
    const auto t2 = Clock::now();
    p.status = "registered";
    {
      std::lock_guard<std::mutex> lock(mutex);
      // A photo placed after it was unregistered keeps its place in arrival order.
      if (auto it = by_name.find(name); it != by_name.end()) {
        photos[it->second] = p;
      } else {
        by_name[name] = photos.size();
        photos.push_back(p);
      }
    }
    std::vector<size_t> targets;
    for (size_t i : Registered())
      if (!photos[i].has_depth) targets.push_back(i);
    for (size_t i : RefreshTargets(by_name[name])) targets.push_back(i);
    // Depth maps made stale by refined poses: at most kStalePerPhoto per photo, oldest first.
    size_t stale = 0;
    for (size_t i : Registered()) {
      if (stale == kStalePerPhoto) break;
      if (photos[i].has_depth && photos[i].depth_stale &&
          std::find(targets.begin(), targets.end(), i) == targets.end()) {
        targets.push_back(i);
        ++stale;
      }
    }
    try {
      EstimateDepth(targets);
    } catch (const std::exception& e) {
      LogWarning(fmt::format("{}: depth estimation failed: {}", name, e.what()));
    }
    // Records of photos whose depth appeared or was refreshed now are appended again (resume
    // keeps it).
    std::vector<Photo> refreshed;
    for (size_t i : targets) {
      if (photos[i].has_depth && photos[i].name != name) refreshed.push_back(photos[i]);
    }
    Put(std::move(refreshed));
    double model_s = 0, suggest_s = 0;
    try {
      RefreshModelAndSuggestions(&model_s, &suggest_s);
    } catch (const std::exception& e) {
      LogWarning(fmt::format("{}: model/suggestion update failed: {}", name, e.what()));
    }
    Photo& me = photos[by_name[name]];
    me.seconds = p.seconds;
    me.seconds["depth"] = Seconds(t2) - model_s - suggest_s;
    me.seconds["model"] = model_s;
    me.seconds["suggest"] = suggest_s;
    me.seconds["total"] = Seconds(t0) + earlier_seconds;
    Put(me);
  }

  void Handle(const std::string& name) {
    const fs::path path = options.watch / name;
    const std::string ext = fs::path(name).extension().string();
    std::string lower = ext;
    for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (lower == ".json") {
      // A sidecar: the photo waiting for it goes ahead.
      const std::string stem = fs::path(name).stem().string();
      for (size_t k = 0; k < waiting.size(); ++k) {
        if (fs::path(waiting[k].name).stem().string() == stem) {
          const std::string photo = waiting[k].name;
          waiting.erase(waiting.begin() + static_cast<long>(k));
          Handle(photo);
          return;
        }
      }
      return;
    }
    Photo p;
    p.name = name;
    p.arrival = next_arrival;
    try {
      scene::CheckedImageName(name, options.watch.string());
    } catch (const std::exception& e) {
      p.status = "bad_name";
      p.message = e.what();
      ++next_arrival;
      Put(p);
      return;
    }
    std::string bytes;
    try {
      bytes = ReadFileToString(path);
    } catch (const std::exception&) {
      return;  // vanished meanwhile
    }
    p.sha256 = Sha256(bytes);
    {
      auto it = by_name.find(name);
      if (it != by_name.end() && photos[it->second].sha256 == p.sha256 &&
          FinalStatus(photos[it->second].status))
        return;  // already processed (a restart)
      if (it != by_name.end() && photos[it->second].status == "registered") {
        // Its depth map and prediction belong to the first content: keep the registration.
        LogWarning(fmt::format("{}: changed after it was registered; the new content is ignored "
                               "(give the new photo another name)",
                               name));
        return;
      }
    }
    if (!io::IsImageFile(path)) {
      p.status = "not_an_image";
      p.message = "not a photo (.png, .jpg, .jpeg, .exr, .pfm)";
      ++next_arrival;
      Put(p);
      return;
    }
    for (size_t i : Registered()) {
      if (photos[i].sha256 == p.sha256 && photos[i].name != name) {
        p.status = "duplicate";
        p.message = "same content as " + photos[i].name;
        ++next_arrival;
        Put(p);
        return;
      }
    }
    Image photo;
    try {
      io::DecodeImage({reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()}, name, &photo);
      REPHOTO_CHECK(photo.width() >= 16 && photo.height() >= 16, "{}: too small", name);
    } catch (const std::exception& e) {
      p.status = "unreadable";
      p.message = e.what();
      ++next_arrival;
      Put(p);
      return;
    }
    p.sharpness = Sharpness(photo);
    const std::vector<size_t> reg = Registered();
    if (options.blur_ratio > 0 && reg.size() >= 3) {
      std::vector<double> s;
      for (size_t i : reg) s.push_back(photos[i].sharpness);
      std::nth_element(s.begin(), s.begin() + s.size() / 2, s.end());
      const double median = s[s.size() / 2];
      if (p.sharpness < options.blur_ratio * median) {
        p.status = "blurred";
        p.message = fmt::format("sharpness {:.3g} is below {} x the median {:.3g} of the photos so far",
                                p.sharpness, options.blur_ratio, median);
        ++next_arrival;
        Put(p);
        return;
      }
    }
    const fs::path sidecar = options.watch / (fs::path(name).stem().string() + ".json");
    std::error_code ec;
    if (!fs::is_regular_file(sidecar, ec) && !options.registrar) {
      for (const Waiting& w : waiting)
        if (w.name == name) return;
      waiting.push_back({name, Clock::now()});
      return;
    }
    const int64_t arrival = next_arrival++;
    try {
      Process(name, arrival, p.sha256, photo, p.sharpness);
      if (options.registrar && (!deferred.empty() || !unplaced.empty())) RetryDeferred();
    } catch (const Error& e) {
      // Bad input of this photo: a status. (Failures to write the run folder propagate from Put.)
      p.arrival = arrival;
      p.status = "failed";
      p.message = e.what();
      {
        std::lock_guard<std::mutex> lock(mutex);
        auto it = by_name.find(name);
        if (it != by_name.end() && it->second + 1 == photos.size() && photos.back().status == "registered" &&
            photos.back().sha256 == p.sha256) {
          photos.pop_back();
          by_name.erase(it);
        }
      }
      Put(p);
    }
  }

  void RebuildApi() {
    nlohmann::json list = nlohmann::json::array();
    std::vector<const Photo*> order;
    for (const Photo& p : photos) order.push_back(&p);
    std::stable_sort(order.begin(), order.end(),
                     [](const Photo* a, const Photo* b) { return a->arrival < b->arrival; });
    std::string latest;
    for (const Photo* p : order) {
      nlohmann::json j = p->Json();
      j.erase("sha256");
      list.push_back(j);
      if (p->status == "registered") latest = p->name;
    }
    std::lock_guard<std::mutex> lock(mutex);
    ++version;
    api = {{"schema", "rephoto.live/1"},
           {"version", version},
           {"watch", options.watch.string()},
           {"photos", list},
           {"waiting", waiting.size() + deferred.size()},
           {"waiting_reason", deferred.empty() ? std::string() : deferred_reason},
           {"latest", latest},
           {"suggestions", suggestions},
           {"model", model},
           {"metric", "1-ncc"}};
  }

  void Publish() {
    RebuildApi();
    nlohmann::json a;
    {
      std::lock_guard<std::mutex> lock(mutex);
      a = api;
    }
    WriteTextFileAtomically(options.out / "live.json",
                            a.dump(1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
  }
};

LiveSession::LiveSession(const LiveOptions& options) : state_(std::make_unique<State>()) {
  options.Check();
  state_->options = options;
  state_->folder = run::OpenRunFolder(options.out, "live");
  for (const char* d : {"photos", "predictions", "errors", "depth", "suggestions"})
    fs::create_directories(options.out / d);
  state_->Resume();
  state_->Publish();
}

LiveSession::~LiveSession() = default;

void LiveSession::HandleReady(const std::string& name) {
  state_->Handle(name);
  state_->Publish();
}

bool LiveSession::Tick() {
  bool changed = false;
  auto& w = state_->waiting;
  for (size_t k = 0; k < w.size();) {
    if (Seconds(w[k].since) >= state_->options.sidecar_wait) {
      Photo p;
      p.name = w[k].name;
      p.arrival = state_->next_arrival++;
      p.status = "no_pose";
      p.message = fmt::format("no sidecar {}.json within {} s and no registration engine (--colmap)",
                              fs::path(p.name).stem().string(), state_->options.sidecar_wait);
      try {
        p.sha256 = Sha256(ReadFileToString(state_->options.watch / p.name));
      } catch (const std::exception&) {
      }
      state_->Put(p);
      w.erase(w.begin() + static_cast<long>(k));
      changed = true;
    } else {
      ++k;
    }
  }
  if (changed) state_->Publish();
  return changed;
}

bool LiveSession::Idle() {
  State& s = *state_;
  if (!s.options.registrar || (s.deferred.empty() && s.unplaced.empty())) return false;
  try {
    if (!s.options.registrar->Idle()) return false;
    if (s.TakeRefinedPoses()) s.BuildModel();
  } catch (const Error& e) {
    LogWarning(fmt::format("registration engine, while idle: {}", e.what()));
    return false;
  }
  s.RetryDeferred();
  s.Publish();
  return true;
}

size_t LiveSession::waiting() const { return state_->waiting.size(); }

nlohmann::json LiveSession::Api() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->api;
}

std::optional<render::Rephoto> LiveSession::Predict(const camera::Camera& camera,
                                                    const camera::Pose& cam_from_world) {
  return state_->Predict(camera, cam_from_world, "");
}

uint64_t LiveSession::version() const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  return state_->version;
}

std::optional<fs::path> LiveSession::FilePath(const std::string& kind, const std::string& name) const {
  std::lock_guard<std::mutex> lock(state_->mutex);
  const fs::path& out = state_->options.out;
  if (kind == "suggestion") {
    for (const auto& s : state_->suggestions)
      if (s.value("name", "") == name && s.value("has_render", false))
        return out / "suggestions" / (name + ".png");
    return std::nullopt;
  }
  auto it = state_->by_name.find(name);
  if (it == state_->by_name.end()) return std::nullopt;
  const Photo& p = state_->photos[it->second];
  if (p.status != "registered") return std::nullopt;
  if (kind == "photo") return out / "photos" / (name + ".png");
  if (!p.has_error_image) return std::nullopt;
  if (kind == "prediction") return out / "predictions" / (name + ".png");
  if (kind == "error") return out / "errors" / (name + ".png");
  return std::nullopt;
}

}  // namespace rephoto::live
