// The closed-loop experiment of issue 31 on the demo scene (docs/live.md): does following
// `rephoto live`'s suggestions cover the object faster and predict unseen views better than
// photos taken at random or continuing the ring?
//
// Setup (demo_capture.h, photos width x height, PINHOLE f = width):
//   start      4 photos on one side: ring of radius 3.2 at height 1.5 looking at (0, 0, 0.45),
//              azimuths 0, 20, 40, 60 degrees;
//   held out   8 fixed views all around: radius 3.0, height 1.0, azimuths 22.5 + 45 k degrees
//              (never photographed; only evaluated);
//   sequences  `steps` further photos, each dropped (PNG + pose sidecar) into the watched folder
//              and handed to a LiveSession (the same pipeline `rephoto live` runs), chosen by
//              - suggested: the first suggestion of the page after the previous photo;
//              - ring: continuing the ring (80, 100, 120, ... degrees);
//              - random: uniformly among `candidates` Fibonacci-sphere directions around
//                (0, 0, 0.45) at the start photos' distance (3.37) whose elevation lies within
//                20 degrees of the start photos' (and above the horizon), the rule of
//                suggest::SuggestViews' candidates; `random_seeds` seeds, median per step.
// Figures after each photo (all independent of the live model):
//   unseen     the area fraction of the object's true surface that no photo sees
//              (UnseenObjectFraction, render/visibility.h's rule on the ground-truth mesh);
//   held-out   the live prediction (LiveSession::Predict: IBR from the 6 nearest photos with their
//              live depth maps)
//              rendered at the 8 held-out views and compared with the true photos there (1-NCC,
//              compare::CompareInMemory): completeness c, error e over the covered windows, and
//              the error of the whole view e_all = c e + (1 - c) * 1 (an uncovered window
//              counts as unrelated content, 1-NCC = 1), each averaged over the 8 views.
// Thread safety: reentrant (one call per work folder).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "rephoto/camera/camera.h"
#include "rephoto/live/live_model.h"

namespace rephoto::live {

struct ClosedLoopOptions {
  std::filesystem::path work;  // folders of the sequences (created)
  int width = 480;
  int height = 360;
  int steps = 8;
  int depth_width = 0;          // the live session's --depth-width (0: min(width, 320))
  int random_seeds = 5;         // 0 = no random sequences
  bool ring = true;             // run the ring sequence
  int candidates = 200;
  int suggest_candidates = 200;
  PlanOptions plan;  // the live session's planner (count and candidates are set from above)
};

struct StepFigures {
  int added = 0;  // photos added after the start
  double unseen = 0;
  double heldout_error = 0;         // e
  double heldout_completeness = 0;  // c
  double heldout_error_all = 0;     // e_all
  double seconds = 0;               // live pipeline seconds for this photo
};

struct Sequence {
  std::string name;
  std::vector<StepFigures> steps;  // step 0 = the start photos only, then one per added photo
};

struct ClosedLoopResult {
  Sequence suggested, ring, random_median;
  std::vector<Sequence> random;
};

ClosedLoopResult RunClosedLoop(const ClosedLoopOptions& options);

// CSV (sequence, added, unseen, heldout_error, heldout_completeness, heldout_error_all) and an
// SVG plot of unseen and heldout_error_all against the photos added.
std::string ClosedLoopCsv(const ClosedLoopResult& result);
std::string ClosedLoopSvg(const ClosedLoopResult& result);

}  // namespace rephoto::live
