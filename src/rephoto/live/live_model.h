// The surface `rephoto live` projects errors onto and plans the next views on, rebuilt after
// every photo from the plane-sweep depth maps of the photos so far (no mesh reconstruction, no
// COLMAP dense step: bounded cost per photo).
//
// Envelope. The photos' depth pixels (every `stride`-th pixel of each depth map, unprojected
// into world points) are binned by direction around a centre c: the point nearest (least
// squares) to the optical axes of all photos, i.e. where the photographer looks (the median of
// the points when the axes are nearly parallel or fewer than 2 photos exist). The directions
// form a latitude/longitude grid about the photos' up direction (UpDirection): `bands`
// latitude rows and `segments` longitudes, one vertex each (plus the two poles).
// A vertex's radius is the 20th percentile of the distances from c of the points in its bin
// (the nearest surface wins over the background behind it, robust to a few stereo outliers
// in front), so the envelope is the star-shaped surface around c that the photos saw.
//
// Multi-view consistency: a depth point counts only when another photo's depth map confirms it
// (it projects inside one of the `consistency_views` depth maps nearest by viewing direction
// whose depth there agrees within `consistency_tolerance`), the usual check of depth-map fusion:
// plane sweep with a distant neighbour leaves outliers that no other photo sees.
// A point counts only when its camera saw it from outside, i.e. the unit vector from the point
// to its camera has a cosine >= 0.1 with the point's direction from c (within 84 degrees):
// background seen past the object (the ground behind it) is not the object's far side. Points
// on the support plane (below) or less than 3 inlier distances above it are the floor's, not
// the object's; the envelope does not reach below the floor (radii are clamped to it, and
// directions whose radius ends on the floor count as observed: the object's contact with the
// floor has nothing to see). An observed radius more than 15 % from the median of its (at
// least 3) observed grid neighbours' is a spike and takes that median; a vertex with fewer than
// 3 observed neighbours (at the edge of what was seen, where plane sweep's wrong floor depths
// beside the object's unseen underside made spikes) is compared with the observed vertices
// within two grid steps instead (at least 3).
// Unseen surface. A direction is *observed* when its bin holds at least `min_points` points
// from at least `min_views` different photos. Every other direction stands for surface no
// photo has looked at yet: the far side of the object (directions no camera looked from), the
// open borders of what was seen (the grid closes them), and thinly seen parts (one photo's
// depth only, unconfirmed). Their radii are filled by harmonic interpolation from the observed
// vertices (Jacobi iterations of the mean of the grid neighbours, observed radii fixed), so the
// envelope is a closed surface whose unobserved part is where the photos stop. Radii are
// clamped to [0.05, 4] times the median observed radius (far background does not blow it up).
//
// Support plane. Object captures stand on something (a floor, a table, the ground), which the
// star-shaped envelope cannot hold: it is seen around and behind the object, far from c. The
// plane holding the most consistent depth points (RANSAC over at most 20 000 of them, 256
// hypotheses from a fixed seed, inlier distance 0.5 % of the cameras' median distance from c,
// then the least-squares plane of the inliers, whose inliers are taken again until they no
// longer change; plane-sweep points of a floor seen at grazing angles err more the farther they
// are, and one refit of RANSAC's band kept 0.2-0.5 degree of tilt on the demo where the fixed
// point keeps 0.01-0.1 degree) is the support plane when it holds at least
// `support_min_fraction` of them, its normal lies within 45 degrees of `up`, and every camera and
// c are on its upper side. It is kept as a mesh of the cells of a 96 x 96 grid over the extent
// of all depth points within the inlier distance that hold at least 2 of them (closed by one
// cell: small holes filled), so it covers only the part of it that the photos saw. Together
// with the envelope it is the proxy of the live prediction (live_session.h).
//
// Units: the photos' world frame. Thread safety: reentrant.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "rephoto/camera/camera.h"
#include "rephoto/core/image.h"
#include "rephoto/mesh/mesh.h"

namespace rephoto::live {

struct EnvelopeOptions {
  int bands = 24;     // latitude rows of vertices between the poles (>= 2)
  int segments = 48;  // longitudes (>= 3)
  int stride = 2;     // depth pixels: every stride-th in x and y
  int min_points = 3;
  int min_views = 2;
  double support_min_fraction = 0.1;  // 0 < f <= 1; > 1 = no support plane
  // Multi-view consistency of the depth points (see above): a point counts only when at least
  // `min_consistent` of the `consistency_views` depth maps nearest to its own (by viewing
  // direction) see it within `consistency_tolerance` (relative depth); 0 = every point counts.
  int min_consistent = 1;
  int consistency_views = 4;
  double consistency_tolerance = 0.02;
};

// A depth map (depth_map_io.h convention: camera-frame z, NaN = unknown) with the camera of its
// pixel grid (scaled to the depth map) and its photo's pose.
struct EnvelopeInput {
  camera::Camera camera;
  camera::Pose cam_from_world;
  const Image* depth = nullptr;
};

struct Envelope {
  mesh::Mesh mesh;                // closed triangle mesh, outward (counter-clockwise) faces
  std::vector<uint8_t> observed;  // per vertex: 1 = observed direction (see above)
  std::vector<float> area;        // per vertex: a third of the area of its faces
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  // True when the centre is the point nearest to the photos' optical axes (they converge: an
  // object-centred capture); false when it fell back to the points' median (nearly parallel
  // axes: a forward-facing capture, which the star-shaped envelope does not model).
  bool converging = false;
  size_t point_count = 0;         // depth points binned
  mesh::Mesh support;             // the support plane's seen cells; no faces when none
  Eigen::Vector4d support_plane = Eigen::Vector4d::Zero();  // n.x, n.y, n.z, d: n.X + d = 0
  double ObservedFraction() const;  // area of observed vertices / total area (0 when empty)
};

// The envelope of the views' depth (see the file comment). `poses` are all photos' poses (for
// the centre and the up direction); `depths` those with a depth map. Throws Error when `poses` is
// empty or the options are invalid. With no depth point at all, a sphere of radius 1/4 of the
// cameras' median distance from c, all unobserved.
Envelope BuildEnvelope(const std::vector<camera::Pose>& poses,
                       const std::vector<EnvelopeInput>& depths, const EnvelopeOptions& options);

// Multi-view consistency (see the file comment): the `consistency_views` depth maps nearest to
// depths[k] by viewing direction, and whether a world point is confirmed by at least
// options.min_consistent of the depth maps `check` (it projects inside one whose depth at that
// pixel, nearest, agrees with its own depth there within options.consistency_tolerance).
std::vector<size_t> ConsistencyViews(size_t k, const std::vector<EnvelopeInput>& depths,
                                     const EnvelopeOptions& options);
bool ConfirmedByDepthMaps(const Eigen::Vector3d& world, const std::vector<size_t>& check,
                          const std::vector<EnvelopeInput>& depths, const EnvelopeOptions& options);

// The photos' up direction. Photos are taken with the camera level (its x axis horizontal), so
// up is the direction orthogonal to all x axes (the smallest eigenvector of sum x x^T), signed
// like the mean of the cameras' -y axes. That mean itself (biased toward the cameras' backs
// when they all look down from one side) is the answer when the x axes are nearly parallel or
// do not share a plane (cameras far from level).
Eigen::Vector3d UpDirection(const std::vector<camera::Pose>& poses);

// The point nearest (least squares) to the optical axes; false when that is ill-conditioned.
bool NearestPointToAxes(const std::vector<camera::Pose>& poses, Eigen::Vector3d* point);

}  // namespace rephoto::live

namespace rephoto::render {
class RenderModel;
}

namespace rephoto::live {

// Next views on the envelope, for a capture in progress (`rephoto live`). Like
// suggest::SuggestViews (candidates on a Fibonacci sphere around the look-at point at the
// photos' median distance, within `elevation_margin_degrees` of the photos' elevation range
// about `up`, not below the horizon when every photo is above it, and not below the support
// plane when there is one; greedy choice of the
// candidate seeing the most weight, whose vertices' weights then drop to 0; visibility by
// suggest::VisibleVertices), with one difference: a candidate must lie within
// [min_gap_degrees, max_gap_degrees] (seen from the look-at point) of the nearest photo taken
// or suggested before it. The lower bound keeps a suggestion from repeating a photo. The upper
// bound keeps some overlap with the photos so far (COLMAP needs matches to register a photo;
// on a convex object two views up to about 90 degrees apart still share part of the surface
// each sees): the live prediction no longer needs a close neighbour (every photo's depth comes
// from the proxy, live_session.h), so the band is wide. With the former 30 degrees (when a
// photo's own plane-sweep depth was its prediction geometry) the closed loop was a frontier
// walk no faster than continuing the ring (docs/live.md). When no candidate satisfies the
// band, max_gap doubles until one does.
// Weight of a vertex = area * need, need in [0, 1] given by the caller; need >= 1 marks unseen
// surface. Once no candidate newly sees enough unseen surface, the choice is by view-space
// coverage instead (PlanOptions::unseen_exhausted_fraction).
struct PlanOptions {
  int count = 3;
  int candidates = 200;
  double elevation_margin_degrees = 20;
  double min_gap_degrees = 8;
  double max_gap_degrees = 90;
  // View-space coverage once the unseen surface is used up. While some candidate newly sees
  // unobserved envelope area (need 1, not yet covered by an earlier pick) of at least this
  // fraction of the envelope's area, the choice is by need-weighted area as above. After that,
  // each candidate is scored by how much it closes the gaps of view space: the decrease of the
  // sum, over the target directions (the candidates within the photos' elevation range, widened
  // by half the candidates' spacing), of the angle to the nearest photo taken or suggested
  // before it that has a stereo partner (another photo within stereo_partner_degrees; 0 = every
  // photo counts). The live prediction's error grows with the angle from a view to the photos
  // it is rendered from, and a photo without a close partner gets poor plane-sweep depth (the
  // proxy keeps only multi-view consistent depth), so an isolated photo covers nothing until a
  // partner is taken. 0 = never (surface only). docs/live.md has the measurements.
  double unseen_exhausted_fraction = 0.15;  // 0.12 until 2026-11-28 (docs/live.md, closed loop)
  double stereo_partner_degrees = 25;
  // While a photo (or an earlier pick) has no other within stereo_partner_degrees, the next
  // pick is among the candidates within that angle of such a photo (scored as above): a lone
  // photo's plane-sweep depth is poor and rarely passes the proxy's consistency check, so its
  // partner is worth more than the next lone photo (docs/live.md, closed loop: lower mean
  // held-out error at every size measured).
  bool partner_first = true;
};

struct PlannedView {
  camera::Pose cam_from_world;
  double score = 0;           // weight it added when chosen
  double unseen_area = 0;     // area of need-1 vertices it newly sees
  size_t visible_vertices = 0;
  bool view_coverage = false;  // chosen by view-space coverage (unseen surface used up)
  double coverage_gain = 0;    // then: mean decrease of the target directions' gap (radians)
};

std::vector<PlannedView> PlanNextViews(const render::RenderModel& surface, const Envelope& env,
                                       const std::vector<float>& need,
                                       const std::vector<camera::Pose>& photos,
                                       const camera::Camera& camera, const PlanOptions& options);

}  // namespace rephoto::live
