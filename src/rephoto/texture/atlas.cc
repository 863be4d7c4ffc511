#include "rephoto/texture/atlas.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <optional>

#include "rephoto/camera/cam_to_image.h"
#include "rephoto/core/error.h"
#include "rephoto/core/parallel.h"
#include "rephoto/io/image_io.h"
#include "rephoto/texture/photo.h"

namespace rephoto::texture {
namespace {

constexpr int kCellSize = 4;  // texels per side of a fill cell

uint32_t Find(std::vector<uint32_t>& parent, uint32_t x) {
  while (parent[x] != x) x = parent[x] = parent[parent[x]];
  return x;
}

struct Patch {
  int label = -1;  // view position; -1 = a fill cell
  std::vector<uint32_t> faces;
  double min_x = 0, min_y = 0;  // bounding box corner in photo pixels
  double scale = 1;             // texels per photo pixel
  int width = 0, height = 0;    // in texels, padding included
  int atlas = 0, x = 0, y = 0;  // placement
};

// The camera of a view at the size its photo file has (header only).
camera::Camera PhotoCamera(const scene::Scene& scene, const scene::View& view) {
  camera::Camera camera = scene.CameraOf(view);
  const io::ImageHeader header = io::ReadImageHeader(view.image_path);
  if (header.width != camera.width || header.height != camera.height) {
    camera = camera.Scaled(header.width, header.height);
  }
  return camera;
}

// Shelf packing (see atlas.h); returns the atlas sizes.
std::vector<std::pair<int, int>> Pack(std::vector<Patch>& patches, int max_size) {
  double area = 0;
  int widest = 1;
  for (const Patch& p : patches) {
    area += static_cast<double>(p.width) * p.height;
    widest = std::max(widest, p.width);
  }
  int width = 64;
  while (width < max_size && (static_cast<double>(width) * width < 1.2 * area || width < widest)) {
    width *= 2;
  }
  width = std::min(width, max_size);
  std::vector<size_t> order(patches.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    if (patches[a].height != patches[b].height) return patches[a].height > patches[b].height;
    if (patches[a].width != patches[b].width) return patches[a].width > patches[b].width;
    return a < b;
  });
  std::vector<std::pair<int, int>> sizes = {{width, 0}};
  int x = 0, y = 0, shelf = 0;
  for (size_t i : order) {
    Patch& p = patches[i];
    if (x + p.width > width) {
      y += shelf;
      x = 0;
      shelf = 0;
    }
    if (y + p.height > max_size) {
      sizes.push_back({width, 0});
      x = y = shelf = 0;
    }
    p.atlas = static_cast<int>(sizes.size()) - 1;
    p.x = x;
    p.y = y;
    x += p.width;
    shelf = std::max(shelf, p.height);
    sizes.back().second = std::max(sizes.back().second, y + p.height);
  }
  return sizes;
}

// A texel of a partially seen face that its own photo does not see (outside the photo or
// hidden); it takes its colour from another photo afterwards.
struct PendingTexel {
  int atlas, x, y;
  Eigen::Vector3f point;
  uint32_t face;
};

// Visibility of single points (the texels of partially seen faces).
struct Occlusion {
  RTCScene scene = nullptr;
  float tfar = 1.0f;
  const std::vector<uint8_t>& partial;  // per face: textured from a photo that sees part of it
  bool Sees(const Photo& photo, const Eigen::Vector3d& point,
            const std::optional<Eigen::Vector2d>& pixel) const {
    if (!pixel || !(pixel->x() >= 0.5 && pixel->x() <= photo.width() - 0.5 && pixel->y() >= 0.5 &&
                    pixel->y() <= photo.height() - 0.5)) {
      return false;
    }
    const Eigen::Vector3d center = photo.cam_from_world().Center();
    const Eigen::Vector3d direction = point - center;
    RTCIntersectContext context;
    rtcInitIntersectContext(&context);
    RTCRay ray;
    ray.org_x = static_cast<float>(center.x());
    ray.org_y = static_cast<float>(center.y());
    ray.org_z = static_cast<float>(center.z());
    ray.dir_x = static_cast<float>(direction.x());
    ray.dir_y = static_cast<float>(direction.y());
    ray.dir_z = static_cast<float>(direction.z());
    ray.tnear = 0.0f;
    ray.tfar = tfar;
    ray.mask = 0xFFFFFFFFu;
    ray.time = 0.0f;
    ray.flags = 0;
    ray.id = 0;
    rtcOccluded1(scene, &context, &ray);
    return ray.tfar >= 0;
  }
};

// Barycentric coordinates of c in triangle q (may be negative outside it).
Eigen::Vector3d Barycentric(const Eigen::Vector2d* q, const Eigen::Vector2d& c) {
  const Eigen::Vector2d e1 = q[1] - q[0], e2 = q[2] - q[0], d = c - q[0];
  const double area2 = e1.x() * e2.y() - e1.y() * e2.x();
  const double b1 = (d.x() * e2.y() - d.y() * e2.x()) / area2;
  const double b2 = (e1.x() * d.y() - e1.y() * d.x()) / area2;
  return {1 - b1 - b2, b1, b2};
}

// Writes a patch's texels into its atlas. Each texel belongs to the face whose texture
// triangle covers its centre (faces' triangles dilated into the padding and gaps); its value
// is the photo at the projection of the 3D point with the texel's barycentric coordinates
// (perspective-correct and following the lens distortion, which a straight copy of the photo
// region would not be for large faces), plus the interpolated seam adjustment. Texels no face
// reaches take the photo straight below them.
void FillPatch(const Patch& patch, const mesh::Mesh& mesh,
               const std::vector<Eigen::Vector2d>& corners, const ColorAdjustment& adjustment,
               const Photo& photo, int padding, const Occlusion& occlusion, Image8* atlas,
               std::vector<PendingTexel>* pending) {
  const int w = patch.width, h = patch.height;
  std::vector<int32_t> owner(static_cast<size_t>(w) * h, -1);  // index into patch.faces
  const Eigen::Vector2d origin(patch.min_x, patch.min_y);
  auto texture_triangle = [&](uint32_t f, Eigen::Vector2d* q) {
    for (int k = 0; k < 3; ++k) {
      q[k] = Eigen::Vector2d::Constant(padding) + (corners[3 * f + k] - origin) * patch.scale;
    }
  };
  for (size_t i = 0; i < patch.faces.size(); ++i) {
    Eigen::Vector2d q[3];
    texture_triangle(patch.faces[i], q);
    const double area2 =
        (q[1] - q[0]).x() * (q[2] - q[0]).y() - (q[1] - q[0]).y() * (q[2] - q[0]).x();
    if (!(std::abs(area2) > 1e-12)) continue;
    const int x0 =
        std::max(0, static_cast<int>(std::floor(std::min({q[0].x(), q[1].x(), q[2].x()}))));
    const int x1 =
        std::min(w - 1, static_cast<int>(std::ceil(std::max({q[0].x(), q[1].x(), q[2].x()}))));
    const int y0 =
        std::max(0, static_cast<int>(std::floor(std::min({q[0].y(), q[1].y(), q[2].y()}))));
    const int y1 =
        std::min(h - 1, static_cast<int>(std::ceil(std::max({q[0].y(), q[1].y(), q[2].y()}))));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const Eigen::Vector3d b = Barycentric(q, Eigen::Vector2d(x + 0.5, y + 0.5));
        if (b.minCoeff() < -1e-9) continue;
        owner[static_cast<size_t>(y) * w + x] = static_cast<int32_t>(i);
      }
    }
  }
  // Dilate the owners into the padding and into gaps between faces (4-neighbours, the first
  // owned neighbour in left, right, up, down order).
  std::vector<int32_t> next = owner;
  for (int round = 0; round < padding + 2; ++round) {
    bool changed = false;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const size_t i = static_cast<size_t>(y) * w + x;
        if (owner[i] >= 0) continue;
        const int nx[4] = {x - 1, x + 1, x, x}, ny[4] = {y, y, y - 1, y + 1};
        for (int k = 0; k < 4; ++k) {
          if (nx[k] < 0 || ny[k] < 0 || nx[k] >= w || ny[k] >= h) continue;
          const int32_t o = owner[static_cast<size_t>(ny[k]) * w + nx[k]];
          if (o >= 0) {
            next[i] = o;
            changed = true;
            break;
          }
        }
      }
    }
    owner = next;
    if (!changed) break;
  }
  for (int y = 0; y < h; ++y) {
    uint8_t* row = atlas->row(patch.y + y) + 3 * patch.x;
    for (int x = 0; x < w; ++x) {
      const int32_t o = owner[static_cast<size_t>(y) * w + x];
      Eigen::Vector3f c;
      if (o < 0) {
        c = photo.Sample(patch.min_x + (x + 0.5 - padding) / patch.scale,
                         patch.min_y + (y + 0.5 - padding) / patch.scale);
      } else {
        const uint32_t f = patch.faces[o];
        Eigen::Vector2d q[3];
        texture_triangle(f, q);
        const Eigen::Vector3d b = Barycentric(q, Eigen::Vector2d(x + 0.5, y + 0.5));
        const mesh::Triangle& t = mesh.faces[f];
        const Eigen::Vector3d point = b[0] * mesh.positions[t[0]].cast<double>() +
                                      b[1] * mesh.positions[t[1]].cast<double>() +
                                      b[2] * mesh.positions[t[2]].cast<double>();
        const auto pixel = photo.Project(point);
        if (occlusion.partial[f] && o >= 0 && !occlusion.Sees(photo, point, pixel)) {
          pending->push_back({patch.atlas, patch.x + x, patch.y + y, point.cast<float>(), f});
        }
        c = pixel ? photo.Sample(pixel->x(), pixel->y())
                  : photo.Sample(patch.min_x + (x + 0.5 - padding) / patch.scale,
                                 patch.min_y + (y + 0.5 - padding) / patch.scale);
        const Eigen::Vector3d bc = b.cwiseMax(0.0) / std::max(b.cwiseMax(0.0).sum(), 1e-12);
        for (int k = 0; k < 3; ++k) {
          c += static_cast<float>(bc[k]) * adjustment.At(t[k], patch.label);
        }
      }
      for (int k = 0; k < 3; ++k) {
        row[3 * x + k] = static_cast<uint8_t>(std::lround(std::clamp(c[k], 0.0f, 1.0f) * 255.0f));
      }
    }
  }
}

// Colours the pending texels from the photo that sees their point best (facing, inside the
// photo, unoccluded; largest cos x (focal / distance)^2, as colorize.h weighs photos); texels
// that no photo sees keep their own photo's colour. Reads every photo once more when there is
// anything pending. Returns how many texels got a colour.
size_t ReassignTexels(const mesh::Mesh& mesh, const std::vector<PendingTexel>& pending,
                      const Occlusion& occlusion, const scene::Scene& scene,
                      const std::vector<size_t>& views, Photo* photo, Atlases* out) {
  if (pending.empty()) return 0;
  std::vector<float> best(pending.size(), 0.0f);
  std::vector<Eigen::Vector3f> colors(pending.size());
  for (size_t l = 0; l < views.size(); ++l) {
    photo->Load(scene, scene.views[views[l]]);
    const Eigen::Vector3d center = photo->cam_from_world().Center();
    const double focal = photo->camera().MeanFocalLength();
    ParallelFor(0, static_cast<int64_t>(pending.size()), 4096, [&](int64_t begin, int64_t end) {
      for (int64_t i = begin; i < end; ++i) {
        const PendingTexel& texel = pending[i];
        const Eigen::Vector3d point = texel.point.cast<double>();
        const mesh::Triangle& t = mesh.faces[texel.face];
        const Eigen::Vector3d p0 = mesh.positions[t[0]].cast<double>();
        const Eigen::Vector3d normal = (mesh.positions[t[1]].cast<double>() - p0)
                                           .cross(mesh.positions[t[2]].cast<double>() - p0)
                                           .normalized();
        const Eigen::Vector3d to_camera = center - point;
        const double distance = to_camera.norm();
        const double cosine = normal.dot(to_camera) / distance;
        if (!(cosine > 0)) continue;
        const double score = cosine * (focal / distance) * (focal / distance);
        if (!(score > best[i])) continue;
        const auto pixel = photo->Project(point);
        if (!occlusion.Sees(*photo, point, pixel)) continue;
        best[i] = static_cast<float>(score);
        colors[i] = photo->Sample(pixel->x(), pixel->y());
      }
    });
  }
  size_t assigned = 0;
  for (size_t i = 0; i < pending.size(); ++i) {
    if (!(best[i] > 0)) continue;
    ++assigned;
    for (int k = 0; k < 3; ++k) {
      out->images[pending[i].atlas].at(pending[i].x, pending[i].y, k) =
          static_cast<uint8_t>(std::lround(std::clamp(colors[i][k], 0.0f, 1.0f) * 255.0f));
    }
  }
  return assigned;
}

}  // namespace

Atlases BuildAtlases(const mesh::Mesh& mesh,
                     const std::vector<std::pair<uint32_t, uint32_t>>& face_pairs,
                     const std::vector<int>& face_labels,
                     const std::vector<Eigen::Vector3f>& fill_colors,
                     const ColorAdjustment& adjustment, const render::RenderModel& model,
                     const std::vector<uint8_t>& partial_faces, const scene::Scene& scene,
                     const std::vector<size_t>& views, const AtlasOptions& options) {
  REPHOTO_CHECK(options.texel_scale > 0 && options.texel_scale <= 1,
                "texture: texel scale {} must be in (0, 1]", options.texel_scale);
  REPHOTO_CHECK(options.max_atlas_size >= 64 && options.padding >= 0 &&
                    options.padding * 4 < options.max_atlas_size,
                "texture: atlas size {} (>= 64) and padding {} do not fit", options.max_atlas_size,
                options.padding);
  const size_t face_count = mesh.faces.size();
  // Patches: same-label components, in order of their first face.
  std::vector<uint32_t> parent(face_count);
  std::iota(parent.begin(), parent.end(), 0u);
  for (const auto& [a, b] : face_pairs) {
    if (face_labels[a] >= 0 && face_labels[a] == face_labels[b]) {
      const uint32_t ra = Find(parent, a), rb = Find(parent, b);
      if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
    }
  }
  std::vector<Patch> patches;
  std::vector<int64_t> patch_of_root(face_count, -1);
  for (size_t f = 0; f < face_count; ++f) {
    const uint32_t root = Find(parent, static_cast<uint32_t>(f));
    if (patch_of_root[root] < 0) {
      patch_of_root[root] = static_cast<int64_t>(patches.size());
      patches.emplace_back();
      patches.back().label = face_labels[f];
    }
    patches[patch_of_root[root]].faces.push_back(static_cast<uint32_t>(f));
  }
  // Corners in photo pixels, patch boxes and sizes.
  std::vector<Eigen::Vector2d> corners(3 * face_count, Eigen::Vector2d::Zero());
  std::vector<std::optional<camera::CamToImage>> cameras(views.size());
  Atlases out;
  for (Patch& patch : patches) {
    if (patch.label < 0) {
      patch.width = patch.height = kCellSize;
      ++out.fill_cells;
      continue;
    }
    ++out.patches;
    const scene::View& view = scene.views[views[patch.label]];
    if (!cameras[patch.label]) cameras[patch.label].emplace(PhotoCamera(scene, view));
    const camera::CamToImage& to_image = *cameras[patch.label];
    double min_x = 1e300, min_y = 1e300, max_x = -1e300, max_y = -1e300;
    for (uint32_t f : patch.faces) {
      for (int k = 0; k < 3; ++k) {
        const auto pixel = to_image(
            view.cam_from_world.CamFromWorld(mesh.positions[mesh.faces[f][k]].cast<double>()));
        const Eigen::Vector2d p = pixel ? *pixel : Eigen::Vector2d(0.5, 0.5);
        corners[3 * f + k] = p;
        min_x = std::min(min_x, p.x()), max_x = std::max(max_x, p.x());
        min_y = std::min(min_y, p.y()), max_y = std::max(max_y, p.y());
      }
    }
    patch.min_x = min_x;
    patch.min_y = min_y;
    const double limit = options.max_atlas_size - 2.0 * options.padding - 1;
    patch.scale = std::min({options.texel_scale, limit / std::max(max_x - min_x, 1e-9),
                            limit / std::max(max_y - min_y, 1e-9)});
    patch.width = static_cast<int>(std::ceil((max_x - min_x) * patch.scale)) + 2 * options.padding;
    patch.height = static_cast<int>(std::ceil((max_y - min_y) * patch.scale)) + 2 * options.padding;
    patch.width = std::max(patch.width, 1);
    patch.height = std::max(patch.height, 1);
  }
  const std::vector<std::pair<int, int>> sizes = Pack(patches, options.max_atlas_size);
  for (const auto& [w, h] : sizes) {
    out.images.emplace_back(w, std::max(h, 1), 3, uint8_t{0});
    out.texels += static_cast<size_t>(w) * std::max(h, 1);
  }
  // Texture coordinates.
  out.wedge_texcoords.resize(3 * face_count);
  out.face_atlas.resize(face_count);
  for (const Patch& patch : patches) {
    const Image8& image = out.images[patch.atlas];
    const float aw = static_cast<float>(image.width()), ah = static_cast<float>(image.height());
    for (uint32_t f : patch.faces) {
      out.face_atlas[f] = patch.atlas;
      for (int k = 0; k < 3; ++k) {
        Eigen::Vector2d t(patch.x + kCellSize / 2.0, patch.y + kCellSize / 2.0);
        if (patch.label >= 0) {
          t = Eigen::Vector2d(patch.x, patch.y) + Eigen::Vector2d::Constant(options.padding) +
              (corners[3 * f + k] - Eigen::Vector2d(patch.min_x, patch.min_y)) * patch.scale;
        }
        out.wedge_texcoords[3 * f + k] =
            Eigen::Vector2f(static_cast<float>(t.x()) / aw, 1.0f - static_cast<float>(t.y()) / ah);
      }
    }
  }
  // Texels: fill cells, then the patches photo by photo.
  for (const Patch& patch : patches) {
    if (patch.label >= 0) continue;
    const Eigen::Vector3f c = fill_colors[patch.faces.front()].cwiseMax(0.0f).cwiseMin(1.0f);
    for (int y = 0; y < kCellSize; ++y) {
      for (int x = 0; x < kCellSize; ++x) {
        for (int k = 0; k < 3; ++k) {
          out.images[patch.atlas].at(patch.x + x, patch.y + y, k) =
              static_cast<uint8_t>(std::lround(c[k] * 255.0f));
        }
      }
    }
  }
  std::vector<std::vector<size_t>> patches_of(views.size());
  for (size_t i = 0; i < patches.size(); ++i) {
    if (patches[i].label >= 0) patches_of[patches[i].label].push_back(i);
  }
  Photo photo;
  const Occlusion occlusion{model.scene(), static_cast<float>(1.0 - options.occlusion_epsilon),
                            partial_faces};
  std::vector<std::vector<PendingTexel>> pending_of_patch(patches.size());
  for (size_t l = 0; l < views.size(); ++l) {
    if (patches_of[l].empty()) continue;
    photo.Load(scene, scene.views[views[l]]);
    const auto& list = patches_of[l];
    ParallelFor(0, static_cast<int64_t>(list.size()), 1, [&](int64_t begin, int64_t end) {
      for (int64_t i = begin; i < end; ++i) {
        const Patch& patch = patches[list[i]];
        FillPatch(patch, mesh, corners, adjustment, photo, options.padding, occlusion,
                  &out.images[patch.atlas], &pending_of_patch[list[i]]);
      }
    });
  }
  std::vector<PendingTexel> pending;
  for (auto& list : pending_of_patch) pending.insert(pending.end(), list.begin(), list.end());
  out.reassigned_texels = ReassignTexels(mesh, pending, occlusion, scene, views, &photo, &out);
  return out;
}

}  // namespace rephoto::texture
