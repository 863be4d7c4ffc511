// rephoto live-experiment --out DIR [--width W --height H --steps N --seeds S] [--depth-width W] [--no-ring]
// The closed-loop experiment of `rephoto live` on the demo scene (src/rephoto/live/closed_loop.h):
// suggested next views against random ones and against continuing the ring. Writes
// DIR/closed_loop.csv, DIR/closed_loop.svg and the sequences' watch/run folders (each run folder
// also gets closed_loop.svg, which its live page shows).
#include <fmt/format.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "command.h"
#include "rephoto/core/error.h"
#include "rephoto/core/file.h"
#include "rephoto/live/closed_loop.h"

namespace rephoto::cli {
namespace {

CommandRunner SetupLiveExperiment(CLI::App& app) {
  auto o = std::make_shared<live::ClosedLoopOptions>();
  auto out = std::make_shared<std::string>();
  app.add_option("--out", *out, "Output folder")->required();
  app.add_option("--width", o->width, "Photo width")->capture_default_str();
  app.add_option("--height", o->height, "Photo height")->capture_default_str();
  app.add_option("--depth-width", o->depth_width,
                 "Plane-sweep width of the live sessions (0 = the photo width up to 320, as rephoto live)")
      ->capture_default_str();
  app.add_option("--steps", o->steps, "Photos added after the 4 start photos")->capture_default_str();
  app.add_option("--seeds", o->random_seeds, "Random sequences (median per step; 0 = none)")->capture_default_str();
  app.add_flag("!--no-ring", o->ring, "Skip the sequence continuing the ring");
  app.add_option("--min-gap", o->plan.min_gap_degrees,
                 "Planner: least angle (degrees, seen from the look-at point) of a suggestion from the photos")
      ->capture_default_str();
  app.add_option("--elevation-margin", o->plan.elevation_margin_degrees,
                 "Planner: candidates within this many degrees of the photos' elevation range")
      ->capture_default_str();
  app.add_option("--max-gap", o->plan.max_gap_degrees,
                 "Planner: largest angle of a suggestion from its nearest photo (doubled when none fits)")
      ->capture_default_str();
  app.add_option("--unseen-exhausted", o->plan.unseen_exhausted_fraction,
                 "Planner: once no candidate sees unseen surface worth this fraction of the model, "
                 "choose by view-space coverage (0 = never)")
      ->capture_default_str();
  app.add_option("--stereo-partner", o->plan.stereo_partner_degrees,
                 "Planner, view-space coverage: a photo counts once another lies within this many degrees (0 = always)")
      ->capture_default_str();
  app.add_flag("--partner-first,!--no-partner-first", o->plan.partner_first,
               "Planner: while a photo has no stereo partner, the next suggestion is one (default; "
               "--no-partner-first turns it off)");
  return [o, out]() {
    live::ClosedLoopOptions options = *o;
    options.work = *out;
    const live::ClosedLoopResult r = live::RunClosedLoop(options);
    WriteTextFileAtomically(options.work / "closed_loop.csv", live::ClosedLoopCsv(r));
    const std::string svg = live::ClosedLoopSvg(r);
    WriteTextFileAtomically(options.work / "closed_loop.svg", svg);
    // Also into every sequence's run folder: its live page (`rephoto live --out RUN`) shows it.
    std::vector<const live::Sequence*> sequences = {&r.suggested, &r.ring};
    for (const live::Sequence& s : r.random) sequences.push_back(&s);
    for (const live::Sequence* s : sequences) {
      const std::filesystem::path run = options.work / s->name / "run";
      std::error_code ec;
      if (!s->name.empty() && std::filesystem::is_directory(run, ec)) {
        WriteTextFileAtomically(run / "closed_loop.svg", svg);
      }
    }
    fmt::print("{}", live::ClosedLoopCsv(r));
    return static_cast<int>(ExitCode::kOk);
  };
}

}  // namespace

REPHOTO_COMMAND(58, "live-experiment",
                "Closed loop of rephoto live on the demo scene (suggested vs random vs ring)",
                SetupLiveExperiment);

}  // namespace rephoto::cli
