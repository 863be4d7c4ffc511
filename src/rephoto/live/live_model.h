// The surface `rephoto live` projects errors onto and plans the next views on, rebuilt after
// every photo from the plane-sweep depth maps of the photos so far (no mesh reconstruction, no
// COLMAP dense step: bounded cost per photo).
//
// Envelope. The photos' depth pixels (every `stride`-th pixel of each depth map, unprojected
// into world points) are binned by direction around a centre c: the point nearest (least
// squares) to the optical axes of all photos, i.e. where the photographer looks (the median of
// the points when the axes are nearly parallel or fewer than 2 photos exist). The directions
// form a latitude/longitude grid about the photos' up direction (the mean of the cameras' -y
// axes): `bands` latitude rows and `segments` longitudes, one vertex each (plus the two poles).
// A vertex's radius is the 20th percentile of the distances from c of the points in its bin
// (the nearest surface wins over the background behind it, robust to a few stereo outliers
// in front), so the envelope is the star-shaped surface around c that the photos saw.
//
// A point counts only when its camera saw it from outside, i.e. the unit vector from the point
// to its camera has a cosine >= 0.1 with the point's direction from c (within 84 degrees):
// background seen past the object (the ground behind it) is not the object's far side.
// Unseen surface. A direction is *observed* when its bin holds at least `min_points` points
// from at least `min_views` different photos. Every other direction stands for surface no
// photo has looked at yet: the far side of the object (directions no camera looked from), the
// open borders of what was seen (the grid closes them), and thinly seen parts (one photo's
// depth only, unconfirmed). Their radii are filled by harmonic interpolation from the observed
// vertices (Jacobi iterations of the mean of the grid neighbours, observed radii fixed), so the
// envelope is a closed surface whose unobserved part is where the photos stop. Radii are
// clamped to [0.05, 4] times the median observed radius (far background does not blow it up).
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
  size_t point_count = 0;         // depth points binned
  double ObservedFraction() const;  // area of observed vertices / total area (0 when empty)
};

// The envelope of the views' depth (see the file comment). `poses` are all photos' poses (for
// the centre and the up direction); `depths` those with a depth map. Throws Error when `poses` is
// empty or the options are invalid. With no depth point at all, a sphere of radius 1/4 of the
// cameras' median distance from c, all unobserved.
Envelope BuildEnvelope(const std::vector<camera::Pose>& poses,
                       const std::vector<EnvelopeInput>& depths, const EnvelopeOptions& options);

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
// about `up` and not below the horizon when every photo is above it; greedy choice of the
// candidate seeing the most weight, whose vertices' weights then drop to 0; visibility by
// suggest::VisibleVertices), with one difference: a candidate must lie within
// [min_gap_degrees, max_gap_degrees] (seen from the look-at point) of the nearest photo taken
// or suggested before it. A live capture can only use a new photo that overlaps earlier ones
// (plane-sweep stereo needs a neighbour within 60 degrees of viewing direction, COLMAP needs
// matches to register it), so the suggestions extend the covered region from its frontier
// instead of jumping to the far side where nothing could be matched. When no candidate
// satisfies the band, max_gap doubles until one does.
// Weight of a vertex = area * need, need in [0, 1] given by the caller.
struct PlanOptions {
  int count = 3;
  int candidates = 200;
  double elevation_margin_degrees = 20;
  double min_gap_degrees = 8;
  double max_gap_degrees = 30;
};

struct PlannedView {
  camera::Pose cam_from_world;
  double score = 0;           // weight it added when chosen
  double unseen_area = 0;     // area of need-1 vertices it newly sees
  size_t visible_vertices = 0;
};

std::vector<PlannedView> PlanNextViews(const render::RenderModel& surface, const Envelope& env,
                                       const std::vector<float>& need,
                                       const std::vector<camera::Pose>& photos,
                                       const camera::Camera& camera, const PlanOptions& options);

}  // namespace rephoto::live
