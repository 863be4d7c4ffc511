#!/usr/bin/python3
"""Screened Poisson surface from an oriented point cloud with Open3D, trimmed by density.

Usage: poisson_mesh.py POINTS.ply OUT_MESH.ply [--depth D|auto] [--trim-quantile Q]
                       [--margin M] [--min-component F] [--threads N]
                       [--subdivide S | --subdivide auto --model SPARSE [--target-pixels P]
                        [--max-triangles T]] [--from-mesh MESH.ply]

POINTS.ply needs x, y, z and nx, ny, nz (normals pointing out of the surface, towards the
cameras; known_poses.py export writes them). Steps:
  1. Poisson reconstruction (Kazhdan & Hoppe 2013, Open3D's implementation) at octree depth D,
     or with 'auto' (default) the depth whose finest cell is at most the median distance between
     neighbouring points (at most --max-depth, 11), so the resolution follows the point density;
  2. trimming: vertices whose Poisson density (how many samples support them) is below the
     Q-quantile of all vertex densities are removed, as are vertices outside the points'
     bounding box enlarged by M times its diagonal (Poisson closes the surface far from data);
  3. connected pieces with fewer than F times the largest piece's triangles are removed;
  4. each triangle is split into 4 (midpoint subdivision) S times: the shape is unchanged, but
     vertex colours (rephoto colorize) get 4^S times as many samples, i.e. finer colour detail.
     'auto' picks the smallest S at which the median edge spans at most P photo pixels (the pixel
     footprint: median over points of distance to the nearest camera / its focal length, from
     the COLMAP text model SPARSE), but stops before the mesh exceeds T triangles.
With --only-depth, only the depth of step 1 is printed (for colmap poisson_mesher).
With --from-mesh, step 1 is skipped and MESH.ply (e.g. from colmap poisson_mesher) is cropped,
cleaned and subdivided instead (its colours and normals are dropped).
Writes a binary PLY with positions (float, the points' frame and units) and triangles, without
colours (`rephoto colorize` colours it from the training photos) and without normals.
Needs Debian python3-open3d and python3-numpy.
"""

import argparse
import math
import os
import sys

import numpy as np


def fail(message):
    print(f"poisson_mesh.py: error: {message}", file=sys.stderr)
    sys.exit(1)


def pixel_footprint(model_dir, points):
    """Median over points of (distance to the nearest camera centre / that camera's focal length):
    the world size of one photo pixel on the surface."""
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    sys.dont_write_bytecode = True  # no __pycache__ next to the scripts
    import known_poses

    try:
        cameras, images = known_poses.read_model(model_dir)
    except known_poses.InputError as e:
        fail(str(e))
    centers = np.array([im["center"] for im in images])
    focal = np.array([cameras[im["camera_id"]]["params"][0] for im in images])
    from scipy.spatial import cKDTree

    distance, index = cKDTree(centers).query(points)
    return float(np.median(distance / focal[index]))


def poisson_depth(args, xyz):
    """--depth D, or 'auto': the depth whose finest octree cell (Open3D: the points' bounding
    cube enlarged 1.1 times, split 2^D times) is at most the median distance between a point and
    its nearest neighbour, clamped to [5, --max-depth]. The surface's resolution then follows the
    point density and not the scene's extent (far, sparse points would coarsen a fixed depth)."""
    if args.depth != "auto":
        try:
            depth = int(args.depth)
        except ValueError:
            fail(f"--depth must be an octree depth or 'auto', got '{args.depth}'")
        if not 1 <= depth <= 14:
            fail(f"--depth must be in [1, 14], got {depth}")
        return depth
    from scipy.spatial import cKDTree

    distance, _ = cKDTree(xyz).query(xyz, k=2)
    spacing = float(np.median(distance[:, 1]))
    extent = float((xyz.max(axis=0) - xyz.min(axis=0)).max())
    if not spacing > 0:
        fail(f"{args.points}: points coincide (median neighbour distance 0): give --depth")
    depth = int(min(max(math.ceil(math.log2(1.1 * extent / spacing)), 5), args.max_depth))
    print(f"point spacing {spacing:.4g}, extent {extent:.4g}: Poisson depth {depth}",
          file=sys.stderr if args.only_depth else sys.stdout)
    return depth


def subdivisions(args, mesh):
    """Midpoint subdivision count: --subdivide N, or 'auto' = until the median edge is at most
    --target-pixels photo pixels (needs --model), within --max-triangles."""
    if args.subdivide != "auto":
        try:
            n = int(args.subdivide)
        except ValueError:
            fail(f"--subdivide must be a count or 'auto', got '{args.subdivide}'")
        if not 0 <= n <= 6:
            fail(f"--subdivide must be in [0, 6], got {n}")
        return n
    if not args.model:
        fail("--subdivide auto needs --model (the COLMAP text model with the cameras)")
    v = np.asarray(mesh.vertices)
    t = np.asarray(mesh.triangles)
    edges = np.linalg.norm(v[t[:, [1, 2, 0]]] - v[t], axis=2)
    target = args.target_pixels * pixel_footprint(args.model, v)
    n, median_edge = 0, float(np.median(edges))
    while median_edge / 2**n > target and len(t) * 4 ** (n + 1) <= args.max_triangles:
        n += 1
    print(f"median edge {median_edge:.4g}, {args.target_pixels:g} photo pixels = {target:.4g} "
          f"model units: {n} subdivision(s)")
    return n


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("points")
    parser.add_argument("out_mesh")
    parser.add_argument("--depth", default="auto")
    parser.add_argument("--max-depth", type=int, default=11)
    parser.add_argument("--trim-quantile", type=float, default=0.1)
    parser.add_argument("--margin", type=float, default=0.02)
    parser.add_argument("--min-component", type=float, default=0.01)
    parser.add_argument("--subdivide", default="0")
    parser.add_argument("--model", default="")
    parser.add_argument("--target-pixels", type=float, default=4.0)
    parser.add_argument("--max-triangles", type=int, default=2000000)
    parser.add_argument("--from-mesh", default="")
    parser.add_argument("--only-depth", action="store_true")
    parser.add_argument("--threads", type=int, default=0)
    args = parser.parse_args()
    if not 0 <= args.trim_quantile < 1:
        fail(f"--trim-quantile must be in [0, 1), got {args.trim_quantile}")
    if args.threads > 0:
        os.environ["OMP_NUM_THREADS"] = str(args.threads)
    try:
        import open3d as o3d  # Debian python3-open3d
    except ImportError:
        fail("Python module open3d not found: install Debian package python3-open3d")
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)

    if not os.path.isfile(args.points):
        fail(f"{args.points}: no such file")
    cloud = o3d.io.read_point_cloud(args.points)
    if len(cloud.points) < 10:
        fail(f"{args.points}: {len(cloud.points)} points, too few for a surface")
    if not cloud.has_normals():
        fail(f"{args.points}: no normals (nx, ny, nz) in the point cloud")

    if args.only_depth:  # for colmap poisson_mesher: the auto depth alone, on stdout
        xyz = np.asarray(cloud.points)
        depth = poisson_depth(args, xyz)
        print(depth)
        return
    depth = args.depth
    if args.from_mesh:
        # A surface made elsewhere (e.g. colmap poisson_mesher, already trimmed): only cropped,
        # cleaned and subdivided here.
        mesh = o3d.io.read_triangle_mesh(args.from_mesh)
        if len(mesh.triangles) == 0:
            fail(f"{args.from_mesh}: no triangles")
        remove = np.zeros(len(mesh.vertices), dtype=bool)
    else:
        depth = poisson_depth(args, np.asarray(cloud.points))
        mesh, densities = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
            cloud, depth=depth, linear_fit=False)
        densities = np.asarray(densities)
        remove = densities < np.quantile(densities, args.trim_quantile)
    xyz = np.asarray(cloud.points)
    lo, hi = xyz.min(axis=0), xyz.max(axis=0)
    pad = args.margin * np.linalg.norm(hi - lo)
    v = np.asarray(mesh.vertices)
    remove |= np.any((v < lo - pad) | (v > hi + pad), axis=1)
    mesh.remove_vertices_by_mask(remove)

    if args.min_component > 0 and len(mesh.triangles) > 0:
        labels, counts, _ = mesh.cluster_connected_triangles()
        labels, counts = np.asarray(labels), np.asarray(counts)
        small = counts < args.min_component * counts.max()
        mesh.remove_triangles_by_mask(small[labels])
        mesh.remove_unreferenced_vertices()
    if len(mesh.triangles) == 0:
        fail(f"{args.points}: the trimmed Poisson surface is empty (lower --trim-quantile?)")
    iterations = subdivisions(args, mesh)
    if iterations > 0:
        mesh = mesh.subdivide_midpoint(number_of_iterations=iterations)

    vertices = np.asarray(mesh.vertices, dtype="<f4")
    faces = np.asarray(mesh.triangles, dtype="<i4")
    comment = (f"Open3D screened Poisson, depth {depth}, density trim quantile "
               f"{args.trim_quantile}" if not args.from_mesh else
               f"cropped and cleaned {os.path.basename(args.from_mesh)}")
    header = ("ply\nformat binary_little_endian 1.0\n"
              f"comment {comment}\n"
              f"element vertex {len(vertices)}\n"
              "property float x\nproperty float y\nproperty float z\n"
              f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    record = np.dtype([("n", "u1"), ("i", "<i4", (3,))])
    face_data = np.empty(len(faces), dtype=record)
    face_data["n"] = 3
    face_data["i"] = faces
    tmp = args.out_mesh + ".tmp"
    with open(tmp, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(vertices.tobytes())
        f.write(face_data.tobytes())
    os.replace(tmp, args.out_mesh)
    print(f"{len(vertices)} vertices, {len(faces)} triangles")


if __name__ == "__main__":
    main()
