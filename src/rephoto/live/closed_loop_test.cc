// The closed loop of issue 31 (closed_loop.h) at 160 x 120, with the criterion's own settings:
// 4 start photos, 8 more, random sequences as the median of 5 seeds. Asserts the part of the
// acceptance criterion that holds (docs/live.md, "Closed loop"): from the 4th added photo on,
// the suggested sequence leaves less of the object's true surface unseen than the ring and the
// random median, at every step. The held-out prediction part holds at 320 x 240 (docs/live.md,
// about 70 s) but not at this size, where every sequence's prediction is poor (depth maps 160
// pixels wide) and their order is noise; it is not asserted, its figures are printed. The unseen fraction is
// ground-truth visibility (UnseenObjectFraction on the demo mesh), independent of the live model.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "rephoto/live/closed_loop.h"
#include "rephoto/live/demo_capture.h"
#include "rephoto/live/live_model.h"
#include "rephoto/testing/testing.h"

namespace rephoto::live {
namespace {

TEST(ClosedLoopTest, SuggestedViewsLeaveLessSurfaceUnseenThanRingAndRandom) {
  ClosedLoopOptions o;
  o.work = testing::MakeTempDir();
  o.width = 160;
  o.height = 120;
  o.steps = 8;
  o.random_seeds = 5;
  const ClosedLoopResult r = RunClosedLoop(o);
  std::printf("%s", ClosedLoopCsv(r).c_str());
  ASSERT_EQ(r.suggested.steps.size(), 9u);
  ASSERT_EQ(r.ring.steps.size(), 9u);
  ASSERT_EQ(r.random_median.steps.size(), 9u);
  for (int k = 4; k <= 8; ++k) {
    EXPECT_LT(r.suggested.steps[k].unseen, r.ring.steps[k].unseen) << "step " << k;
    EXPECT_LT(r.suggested.steps[k].unseen, r.random_median.steps[k].unseen) << "step " << k;
  }
  // Every sequence's held-out prediction improves over the start (the live prediction uses the
  // photos it gets).
  for (const Sequence* s : {&r.suggested, &r.ring, &r.random_median})
    EXPECT_LT(s->steps.back().heldout_error_all, s->steps.front().heldout_error_all) << s->name;
}

TEST(ClosedLoopTest, ConvergingAxesTellObjectCentredFromForwardFacing) {
  // Cameras around a point converge on it; cameras side by side looking the same way do not
  // (the forward-facing case, where the live prediction keeps plane-sweep depth).
  std::vector<camera::Pose> ring, forward;
  for (int k = 0; k < 4; ++k) {
    const double a = k * 20 * M_PI / 180;
    ring.push_back(LookAt({3.2 * std::cos(a), 3.2 * std::sin(a), 1.5}, {0, 0, 0.45}));
    forward.push_back(LookAt({0.1 * k, -3, 1}, {0.1 * k, 0, 1}));
  }
  Eigen::Vector3d c;
  EXPECT_TRUE(NearestPointToAxes(ring, &c));
  EXPECT_NEAR((c - Eigen::Vector3d(0, 0, 0.45)).norm(), 0.0, 1e-9);
  EXPECT_FALSE(NearestPointToAxes(forward, &c));
  EXPECT_TRUE(BuildEnvelope(ring, {}, EnvelopeOptions()).converging);
  EXPECT_FALSE(BuildEnvelope(forward, {}, EnvelopeOptions()).converging);
}

}  // namespace
}  // namespace rephoto::live
