#include "rephoto/live/closed_loop.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <random>

#include "rephoto/compare/compare.h"
#include "rephoto/core/error.h"
#include "rephoto/core/stats.h"
#include "rephoto/ibr/image_based_renderer.h"
#include "rephoto/live/demo_capture.h"
#include "rephoto/live/live_session.h"
#include "rephoto/live/sidecar.h"

namespace rephoto::live {
namespace fs = std::filesystem;

namespace {

const Eigen::Vector3d kTarget(0, 0, 0.45);

camera::Pose RingPose(double degrees, double radius, double height) {
  const double a = degrees * M_PI / 180;
  return LookAt({radius * std::cos(a), radius * std::sin(a), height}, kTarget);
}

struct Heldout {
  camera::Pose pose;
  Image photo;
};

StepFigures Measure(const DemoCapture& capture, const std::vector<Heldout>& heldout,
                    const std::vector<camera::Pose>& poses, LiveSession& session) {
  StepFigures f;
  f.unseen = UnseenObjectFraction(capture, poses);
  double e = 0, c = 0, all = 0;
  for (const Heldout& h : heldout) {
    // The live prediction itself (LiveSession::Predict), as the page would show it there.
    double ce = 1, cc = 0;
    if (const std::optional<render::Rephoto> rp = session.Predict(capture.camera(), h.pose)) {
      compare::CompareOptions co;
      co.metrics = {metrics::Metric::kOneMinusNcc};
      compare::CompareWorkspace ws;
      const compare::ImageResult res =
          compare::CompareInMemory(co, h.photo, rp->color, nullptr, nullptr, nullptr, &ws);
      cc = std::isfinite(res.completeness.value) ? res.completeness.value : 0.0;
      ce = std::isfinite(res.metrics[0].mean) ? res.metrics[0].mean : 1.0;
    }
    e += ce;
    c += cc;
    all += cc * ce + (1 - cc);
  }
  const double n = static_cast<double>(heldout.size());
  f.heldout_error = e / n;
  f.heldout_completeness = c / n;
  f.heldout_error_all = all / n;
  return f;
}

using Policy = std::function<camera::Pose(const LiveSession& session, int step)>;

Sequence RunSequence(const std::string& name, const ClosedLoopOptions& options,
                     const DemoCapture& capture, const std::vector<Heldout>& heldout,
                     const Policy& policy) {
  const fs::path dir = options.work / name;
  fs::remove_all(dir);
  const fs::path watch = dir / "watch", run = dir / "run";
  fs::create_directories(watch);
  LiveOptions lo;
  lo.watch = watch;
  lo.out = run;
  lo.predict_width = options.width;
  lo.depth_width = options.depth_width > 0 ? options.depth_width : std::min(options.width, 320);
  lo.candidates = options.suggest_candidates;
  lo.plan = options.plan;
  LiveSession session(lo);
  std::vector<camera::Pose> poses;
  Sequence seq;
  seq.name = name;
  int index = 0;
  auto add = [&](const camera::Pose& pose) {
    const std::string stem = fmt::format("{:02d}", index);
    capture.Drop(watch, stem, pose, static_cast<uint64_t>(index) + 1);
    const auto t0 = std::chrono::steady_clock::now();
    session.HandleReady(stem + ".png");
    ++index;
    poses.push_back(pose);
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  for (double a : {0.0, 20.0, 40.0, 60.0}) add(RingPose(a, 3.2, 1.5));
  StepFigures f0 = Measure(capture, heldout, poses, session);
  seq.steps.push_back(f0);
  for (int k = 1; k <= options.steps; ++k) {
    const double s = add(policy(session, k));
    StepFigures f = Measure(capture, heldout, poses, session);
    f.added = k;
    f.seconds = s;
    seq.steps.push_back(f);
  }
  return seq;
}

std::vector<camera::Pose> Candidates(int count) {
  // Fibonacci sphere around the target at the start photos' distance; elevation within 20
  // degrees of the start photos' and above the horizon (SuggestViews' candidate rule).
  const double distance = std::hypot(3.2, 1.5 - kTarget.z());
  const double elevation = std::asin((1.5 - kTarget.z()) / distance);
  const double low = std::max(0.0, elevation - 20 * M_PI / 180), high = elevation + 20 * M_PI / 180;
  std::vector<camera::Pose> out;
  const double golden = M_PI * (3 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    const double z = 1 - 2 * (i + 0.5) / count;
    const double r = std::sqrt(1 - z * z), phi = golden * i;
    const Eigen::Vector3d d(r * std::cos(phi), r * std::sin(phi), z);
    const double el = std::asin(z);
    if (el < low || el > high) continue;
    out.push_back(LookAt(kTarget + distance * d, kTarget));
  }
  return out;
}

}  // namespace

ClosedLoopResult RunClosedLoop(const ClosedLoopOptions& options) {
  REPHOTO_CHECK_USAGE(options.steps >= 1 && options.random_seeds >= 0 && options.width >= 64 &&
                          options.height >= 48,
                      "closed loop: invalid options");
  fs::create_directories(options.work);
  const DemoCapture capture(options.width, options.height);
  std::vector<Heldout> heldout;
  for (int k = 0; k < 8; ++k) {
    const camera::Pose p = RingPose(22.5 + 45 * k, 3.0, 1.0);
    heldout.push_back({p, capture.Photograph(p, 1000 + k)});
  }
  ClosedLoopResult result;
  result.suggested = RunSequence("suggested", options, capture, heldout,
                                 [](const LiveSession& session, int) {
                                   const nlohmann::json api = session.Api();
                                   REPHOTO_CHECK(!api["suggestions"].empty(), "no suggestion");
                                   return ParseSidecar(api["suggestions"][0].dump(), "suggestion")
                                       .cam_from_world;
                                 });
  if (options.ring)
    result.ring = RunSequence("ring", options, capture, heldout, [](const LiveSession&, int k) {
    return RingPose(60.0 + 20.0 * k, 3.2, 1.5);
  });
  const std::vector<camera::Pose> candidates = Candidates(options.candidates);
  for (int s = 0; s < options.random_seeds; ++s) {
    std::mt19937_64 rng(static_cast<uint64_t>(s) + 1);
    std::vector<camera::Pose> order = candidates;
    std::shuffle(order.begin(), order.end(), rng);
    result.random.push_back(RunSequence(fmt::format("random_{}", s), options, capture, heldout,
                                        [order](const LiveSession&, int k) { return order[k - 1]; }));
  }
  result.random_median.name = "random_median";
  for (size_t k = 0; k < result.suggested.steps.size() && !result.random.empty(); ++k) {
    auto median = [&](auto field) {
      std::vector<double> v;
      for (const Sequence& s : result.random) v.push_back(field(s.steps[k]));
      return Quantile(v, 0.5);
    };
    StepFigures f;
    f.added = static_cast<int>(k);
    f.unseen = median([](const StepFigures& x) { return x.unseen; });
    f.heldout_error = median([](const StepFigures& x) { return x.heldout_error; });
    f.heldout_completeness = median([](const StepFigures& x) { return x.heldout_completeness; });
    f.heldout_error_all = median([](const StepFigures& x) { return x.heldout_error_all; });
    f.seconds = median([](const StepFigures& x) { return x.seconds; });
    result.random_median.steps.push_back(f);
  }
  return result;
}

std::string ClosedLoopCsv(const ClosedLoopResult& r) {
  std::string out = "sequence,added,unseen,heldout_error,heldout_completeness,heldout_error_all,seconds\n";
  auto rows = [&](const Sequence& s) {
    for (const StepFigures& f : s.steps)
      out += fmt::format("{},{},{:.5f},{:.5f},{:.5f},{:.5f},{:.3f}\n", s.name, f.added, f.unseen,
                         f.heldout_error, f.heldout_completeness, f.heldout_error_all, f.seconds);
  };
  rows(r.suggested);
  rows(r.ring);
  rows(r.random_median);
  for (const Sequence& s : r.random) rows(s);
  return out;
}

std::string ClosedLoopSvg(const ClosedLoopResult& r) {
  const int W = 760, H = 300, panel = 360, L = 45, T = 30, B = 40;
  std::string svg = fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" font-family=\"sans-serif\" "
      "font-size=\"11\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n",
      W, H);
  struct Line {
    const Sequence* s;
    const char* colour;
    const char* label;
  };
  std::vector<Line> lines;
  for (const Line& l : {Line{&r.suggested, "#d62728", "suggested"},
                        Line{&r.random_median, "#7f7f7f", "random (median of seeds)"},
                        Line{&r.ring, "#1f77b4", "continuing the ring"}})
    if (!l.s->steps.empty()) lines.push_back(l);
  const int n = static_cast<int>(r.suggested.steps.size());
  for (int p = 0; p < 2; ++p) {
    const int x0 = p * (panel + 30) + L, w = panel - L, h = H - T - B;
    double top = 0;
    for (const Line& l : lines)
      for (const StepFigures& f : l.s->steps) top = std::max(top, p == 0 ? f.unseen : f.heldout_error_all);
    top = std::ceil(top * 10 + 0.5) / 10;
    svg += fmt::format("<text x=\"{}\" y=\"18\" font-size=\"13\">{}</text>\n", x0,
                       p == 0 ? "unseen fraction of the object (truth)"
                              : "held-out 1-NCC, uncovered = 1 (8 views)");
    svg += fmt::format("<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"#999\"/>\n",
                       x0, T, w, h);
    for (int t = 0; t <= 4; ++t) {
      const double v = top * t / 4;
      const double y = T + h - h * t / 4.0;
      svg += fmt::format("<text x=\"{}\" y=\"{:.1f}\" text-anchor=\"end\">{:.2f}</text>\n", x0 - 4, y + 4, v);
    }
    for (int k = 0; k < n; ++k) {
      svg += fmt::format("<text x=\"{:.1f}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n",
                         x0 + w * k / double(n - 1), T + h + 14, k);
    }
    svg += fmt::format("<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">photos added after the 4 start photos</text>\n",
                       x0 + w / 2, T + h + 30);
    for (const Line& l : lines) {
      std::string d;
      for (int k = 0; k < n; ++k) {
        const double v = p == 0 ? l.s->steps[k].unseen : l.s->steps[k].heldout_error_all;
        d += fmt::format("{}{:.1f} {:.1f}", k ? " L" : "M", x0 + w * k / double(n - 1),
                         T + h - h * v / top);
      }
      svg += fmt::format("<path d=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"2\"/>\n", d, l.colour);
    }
  }
  int y = T + 10;
  for (const Line& l : lines) {
    svg += fmt::format("<rect x=\"{}\" y=\"{}\" width=\"12\" height=\"3\" fill=\"{}\"/><text x=\"{}\" y=\"{}\">{}</text>\n",
                       W - 190, y, l.colour, W - 174, y + 4, l.label);
    y += 14;
  }
  svg += "</svg>\n";
  return svg;
}

}  // namespace rephoto::live
