#!/usr/bin/python3
"""COLMAP helpers for triangulating with KNOWN camera poses (used by colmap_*.sh here).

Subcommands (each exits with a one-line "known_poses.py: error: ..." message on bad input):

  list SPARSE IMAGE_DIR OUT_LIST
      Writes the image names of SPARSE/images.txt, one per line, for
      `colmap feature_extractor --image_list_path`. Names without a photo in IMAGE_DIR are
      skipped (and reported); fails if fewer than 2 photos remain.

  prepare SPARSE DATABASE OUT_MODEL [--pairs FILE --neighbors K --max-angle DEG]
      Makes a COLMAP database written by `feature_extractor` agree with the known model, as
      `point_triangulator` requires:
      - the database's cameras are replaced by the model's (same ids, model, size, parameters), and
        every database image points to its model camera;
      - if a photo's pixel size differs from its model camera's size by a uniform factor (a
        down-scaled copy of the photos), its keypoints are rescaled to the camera's pixels;
      - OUT_MODEL/{cameras,images,points3D}.txt is the model with the DATABASE's image ids
        (matched by name), no 2D points and no 3D points; model images absent from the database
        (no photo) are left out.
      With --pairs it also writes an image-pair list for `colmap matches_importer` chosen from the
      known poses: each image is paired with its K nearest cameras (by centre distance) whose
      viewing directions differ by at most DEG degrees.

  export MODEL OUT_PLY [--neighbors K] [--min-track N] [--max-error PX]
                       [--outlier-std S] [--outlier-neighbors M]
      Reads a triangulated COLMAP text model and writes its 3D points as a binary PLY with
      x, y, z (float, model frame and units), nx, ny, nz (unit normals from a PCA of the K nearest
      points, each oriented towards the cameras that observed the point) and red, green, blue
      (uchar, the colours COLMAP averaged from the photos). Points seen in fewer than N images or
      with a mean reprojection error above PX pixels are dropped, and so are statistical
      outliers: points whose mean distance to their M (default 20) nearest points exceeds the
      mean over all points by S (default 2; 0 = keep all) standard deviations.

Only the Python standard library plus numpy and scipy (Debian python3-numpy, python3-scipy).
"""

import argparse
import math
import os
import sqlite3
import struct
import sys

import numpy as np

# COLMAP camera model ids (colmap/src/base/camera_models.h) and parameter counts.
CAMERA_MODELS = {
    "SIMPLE_PINHOLE": (0, 3),
    "PINHOLE": (1, 4),
    "SIMPLE_RADIAL": (2, 4),
    "RADIAL": (3, 5),
    "OPENCV": (4, 8),
    "OPENCV_FISHEYE": (5, 8),
    "FULL_OPENCV": (6, 12),
    "FOV": (7, 5),
    "SIMPLE_RADIAL_FISHEYE": (8, 4),
    "RADIAL_FISHEYE": (9, 5),
    "THIN_PRISM_FISHEYE": (10, 12),
}


class InputError(Exception):
    pass


def fail(message):
    raise InputError(message)


def data_lines(path):
    """Yields (line_number, line) of a COLMAP text file, skipping comments."""
    try:
        with open(path, "r", encoding="utf-8") as f:
            lines = f.read().split("\n")
    except OSError as e:
        fail(f"{path}: cannot read ({e.strerror})")
    return lines


def read_cameras(path):
    cameras = {}
    for number, line in enumerate(data_lines(path), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        words = line.split()
        if len(words) < 4:
            fail(f"{path}: line {number}: expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]")
        try:
            camera_id, width, height = int(words[0]), int(words[2]), int(words[3])
            params = [float(w) for w in words[4:]]
        except ValueError:
            fail(f"{path}: line {number}: not a number in '{line}'")
        model = words[1]
        if model not in CAMERA_MODELS:
            fail(f"{path}: line {number}: unknown camera model '{model}'")
        if len(params) != CAMERA_MODELS[model][1]:
            fail(f"{path}: line {number}: {model} needs {CAMERA_MODELS[model][1]} parameters, "
                 f"got {len(params)}")
        if width <= 0 or height <= 0 or not all(math.isfinite(p) for p in params):
            fail(f"{path}: line {number}: bad size or non-finite parameter")
        if camera_id in cameras:
            fail(f"{path}: line {number}: camera id {camera_id} repeated")
        cameras[camera_id] = {"model": model, "width": width, "height": height, "params": params,
                              "line": line}
    if not cameras:
        fail(f"{path}: no cameras")
    return cameras


def quat_to_matrix(qw, qx, qy, qz):
    n = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    if not (n > 0 and math.isfinite(n)):
        return None
    qw, qx, qy, qz = qw / n, qx / n, qy / n, qz / n
    return np.array([
        [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy)],
        [2 * (qx * qy + qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qw * qx)],
        [2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)],
    ])


def read_images(path, cameras=None):
    """Returns a list of dicts: id, q (w,x,y,z), t, camera_id, name, R, center, points2D line."""
    lines = data_lines(path)
    images = []
    names = set()
    i = 0
    while i < len(lines):
        line = lines[i].strip()
        number = i + 1
        i += 1
        if not line or line.startswith("#"):
            continue
        # As COLMAP's reader: the line after an image line holds its 2D points (maybe empty).
        points_line = lines[i] if i < len(lines) else ""
        i += 1
        words = line.split(None, 9)
        if len(words) < 10:
            fail(f"{path}: line {number}: expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME")
        try:
            image_id = int(words[0])
            q = [float(w) for w in words[1:5]]
            t = np.array([float(w) for w in words[5:8]])
            camera_id = int(words[8])
        except ValueError:
            fail(f"{path}: line {number}: not a number in '{line}'")
        name = words[9].strip()
        R = quat_to_matrix(*q)
        if R is None or not np.all(np.isfinite(t)):
            fail(f"{path}: line {number}: bad pose (zero or non-finite quaternion or translation)")
        if cameras is not None and camera_id not in cameras:
            fail(f"{path}: line {number}: camera id {camera_id} is not in cameras.txt")
        if name in names:
            fail(f"{path}: line {number}: image name '{name}' repeated")
        names.add(name)
        images.append({"id": image_id, "q": q, "t": t, "camera_id": camera_id, "name": name,
                       "R": R, "center": -R.T @ t, "points2D": points_line.strip(),
                       "line": number})
    if not images:
        fail(f"{path}: no images")
    return images


def read_model(sparse):
    for f in ("cameras.txt", "images.txt"):
        if not os.path.isfile(os.path.join(sparse, f)):
            fail(f"{sparse}: no {f} (expected a COLMAP text model)")
    cameras = read_cameras(os.path.join(sparse, "cameras.txt"))
    images = read_images(os.path.join(sparse, "images.txt"), cameras)
    return cameras, images


def cmd_list(args):
    _, images = read_model(args.sparse)
    present = [im["name"] for im in images
               if os.path.isfile(os.path.join(args.image_dir, im["name"]))]
    missing = len(images) - len(present)
    if len(present) < 2:
        fail(f"{args.image_dir}: only {len(present)} of the {len(images)} photos named in "
             f"{args.sparse}/images.txt exist: at least 2 are needed")
    with open(args.out_list, "w", encoding="utf-8") as f:
        for name in present:
            f.write(name + "\n")
    message = f"{len(present)} images"
    if missing:
        first = next(im["name"] for im in images if im["name"] not in set(present))
        message += f" ({missing} named in images.txt have no photo and are skipped, e.g. '{first}')"
    print(message)


def choose_pairs(images, neighbors, max_angle_deg):
    """Pairs (i, j), i < j, by known poses: K nearest centres with similar viewing direction."""
    centers = np.array([im["center"] for im in images])
    axes = np.array([im["R"][2, :] for im in images])  # optical axis (camera +z) in world
    cos_max = math.cos(math.radians(max_angle_deg))
    pairs = set()
    for i in range(len(images)):
        d = np.linalg.norm(centers - centers[i], axis=1)
        ok = (axes @ axes[i]) >= cos_max
        ok[i] = False
        candidates = np.nonzero(ok)[0]
        if candidates.size == 0:  # no similar view: fall back to the nearest centres
            candidates = np.array([j for j in range(len(images)) if j != i], dtype=int)
        for j in candidates[np.argsort(d[candidates], kind="stable")][:neighbors]:
            pairs.add((min(i, int(j)), max(i, int(j))))
    return sorted(pairs)


def cmd_prepare(args):
    cameras, images = read_model(args.sparse)
    if not os.path.isfile(args.database):
        fail(f"{args.database}: no such database")
    db = sqlite3.connect(args.database)
    try:
        rows = db.execute(
            "SELECT images.image_id, images.name, cameras.width, cameras.height "
            "FROM images JOIN cameras ON images.camera_id = cameras.camera_id").fetchall()
        by_name = {name: (image_id, w, h) for image_id, name, w, h in rows}
        missing = [im["name"] for im in images if im["name"] not in by_name]
        images = [im for im in images if im["name"] in by_name]
        if len(images) < 2:
            fail(f"{args.database}: only {len(images)} model image(s) have features: at least 2 "
                 f"are needed")
        extra = set(by_name) - {im["name"] for im in images}
        if extra:
            fail(f"{args.database}: holds images that are not in the model, e.g. "
                 f"'{sorted(extra)[0]}' (use a fresh database)")
        rescaled = 0
        with db:  # one transaction
            for im in images:
                image_id, w, h = by_name[im["name"]]
                cam = cameras[im["camera_id"]]
                sx, sy = cam["width"] / w, cam["height"] / h
                if abs(sx / sy - 1) > 0.01:
                    fail(f"{args.database}: photo '{im['name']}' is {w}x{h} but its camera "
                         f"{im['camera_id']} is {cam['width']}x{cam['height']} (different aspect)")
                if abs(sx - 1) > 1e-9 or abs(sy - 1) > 1e-9:
                    row = db.execute("SELECT rows, cols, data FROM keypoints WHERE image_id = ?",
                                     (image_id,)).fetchone()
                    if row and row[0] > 0:
                        kp = np.frombuffer(row[2], dtype=np.float32).reshape(row[0], row[1]).copy()
                        kp[:, 0] *= sx
                        kp[:, 1] *= sy
                        if row[1] == 4:  # x, y, scale, orientation
                            kp[:, 2] *= math.sqrt(sx * sy)
                        elif row[1] == 6:  # x, y, affine shape a11 a12 a21 a22
                            kp[:, 2:6] *= math.sqrt(sx * sy)
                        db.execute("UPDATE keypoints SET data = ? WHERE image_id = ?",
                                   (kp.tobytes(), image_id))
                    rescaled += 1
            db.execute("UPDATE images SET camera_id = -1")
            db.execute("DELETE FROM cameras")
            for camera_id, cam in cameras.items():
                model_id = CAMERA_MODELS[cam["model"]][0]
                blob = struct.pack(f"<{len(cam['params'])}d", *cam["params"])
                db.execute("INSERT INTO cameras (camera_id, model, width, height, params, "
                           "prior_focal_length) VALUES (?, ?, ?, ?, ?, 1)",
                           (camera_id, model_id, cam["width"], cam["height"], blob))
            for im in images:
                image_id = by_name[im["name"]][0]
                c = im["center"]
                db.execute("UPDATE images SET camera_id = ?, prior_qw = ?, prior_qx = ?, "
                           "prior_qy = ?, prior_qz = ?, prior_tx = ?, prior_ty = ?, prior_tz = ? "
                           "WHERE image_id = ?",
                           (im["camera_id"], *im["q"], float(c[0]), float(c[1]), float(c[2]),
                            image_id))
    finally:
        db.close()

    os.makedirs(args.out_model, exist_ok=True)
    used = sorted({im["camera_id"] for im in images})
    with open(os.path.join(args.out_model, "cameras.txt"), "w", encoding="utf-8") as f:
        f.write("# CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[] (known intrinsics)\n")
        for camera_id in used:
            cam = cameras[camera_id]
            f.write(f"{camera_id} {cam['model']} {cam['width']} {cam['height']} "
                    + " ".join(repr(p) for p in cam["params"]) + "\n")
    with open(os.path.join(args.out_model, "images.txt"), "w", encoding="utf-8") as f:
        f.write("# IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME (known poses; ids of "
                "the database)\n# POINTS2D[] left empty\n")
        for im in sorted(images, key=lambda im: by_name[im["name"]][0]):
            f.write(f"{by_name[im['name']][0]} " + " ".join(repr(v) for v in im["q"]) + " "
                    + " ".join(repr(float(v)) for v in im["t"])
                    + f" {im['camera_id']} {im['name']}\n\n")
    with open(os.path.join(args.out_model, "points3D.txt"), "w", encoding="utf-8") as f:
        f.write("# POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] (empty)\n")

    message = f"{len(images)} images, {len(used)} camera(s)"
    if missing:
        message += f" ({len(missing)} without a photo or features skipped, e.g. '{missing[0]}')"
    if rescaled:
        message += f", keypoints of {rescaled} image(s) rescaled to the camera size"
    if args.pairs:
        pairs = choose_pairs(images, args.neighbors, args.max_angle)
        with open(args.pairs, "w", encoding="utf-8") as f:
            for i, j in pairs:
                f.write(f"{images[i]['name']} {images[j]['name']}\n")
        message += f", {len(pairs)} pairs from the poses"
    print(message)


def read_points3d(path):
    """Returns xyz (N,3), rgb (N,3) uint8, error (N,), tracks (list of image-id arrays)."""
    xyz, rgb, err, tracks = [], [], [], []
    for number, line in enumerate(data_lines(path), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        words = line.split()
        if len(words) < 8 or (len(words) - 8) % 2:
            fail(f"{path}: line {number}: expected POINT3D_ID X Y Z R G B ERROR TRACK[]")
        try:
            xyz.append([float(w) for w in words[1:4]])
            rgb.append([int(w) for w in words[4:7]])
            err.append(float(words[7]))
            tracks.append(np.array([int(w) for w in words[8::2]], dtype=np.int64))
        except ValueError:
            fail(f"{path}: line {number}: not a number")
    return (np.array(xyz, dtype=np.float64).reshape(-1, 3),
            np.clip(np.array(rgb, dtype=np.int64).reshape(-1, 3), 0, 255).astype(np.uint8),
            np.array(err), tracks)


def pca_normals(xyz, k):
    from scipy.spatial import cKDTree  # Debian python3-scipy

    k = max(3, min(k, len(xyz)))
    _, idx = cKDTree(xyz).query(xyz, k=k)
    nb = xyz[idx]  # (N, k, 3)
    nb = nb - nb.mean(axis=1, keepdims=True)
    cov = np.einsum("nki,nkj->nij", nb, nb)
    _, vecs = np.linalg.eigh(cov)  # ascending eigenvalues: column 0 = smallest = normal
    return vecs[:, :, 0]


def write_ply(path, xyz, normals, rgb):
    n = len(xyz)
    header = ("ply\nformat binary_little_endian 1.0\n"
              "comment triangulated by COLMAP point_triangulator with known poses\n"
              f"element vertex {n}\n"
              "property float x\nproperty float y\nproperty float z\n"
              "property float nx\nproperty float ny\nproperty float nz\n"
              "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n")
    record = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("nx", "<f4"), ("ny", "<f4"),
                       ("nz", "<f4"), ("r", "u1"), ("g", "u1"), ("b", "u1")])
    data = np.empty(n, dtype=record)
    for i, name in enumerate(("x", "y", "z")):
        data[name] = xyz[:, i]
    for i, name in enumerate(("nx", "ny", "nz")):
        data[name] = normals[:, i]
    for i, name in enumerate(("r", "g", "b")):
        data[name] = rgb[:, i]
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(data.tobytes())
    os.replace(tmp, path)


def cmd_export(args):
    _, images = read_model(args.model)
    centers = {im["id"]: im["center"] for im in images}
    xyz, rgb, err, tracks = read_points3d(os.path.join(args.model, "points3D.txt"))
    keep = np.array([len(np.unique(t)) >= args.min_track for t in tracks], dtype=bool)
    if args.max_error > 0:
        keep &= err <= args.max_error
    if keep.sum() < 3:
        fail(f"{args.model}/points3D.txt: only {int(keep.sum())} point(s) with track length >= "
             f"{args.min_track}: too few to export (did matching fail?)")
    n_total = len(keep)
    xyz, rgb = xyz[keep], rgb[keep]
    tracks = [t for t, k in zip(tracks, keep) if k]
    if args.outlier_std > 0 and len(xyz) > args.outlier_neighbors:
        # Statistical outlier removal (as PCL/Open3D): a point whose mean distance to its K
        # nearest neighbours exceeds the mean of that over all points by S standard deviations
        # is dropped. Isolated wrong triangulations would otherwise float in front of the
        # cameras and inflate the bounding box (and so coarsen the Poisson octree).
        from scipy.spatial import cKDTree

        distance, _ = cKDTree(xyz).query(xyz, k=args.outlier_neighbors + 1)
        mean_distance = distance[:, 1:].mean(axis=1)
        inlier = mean_distance <= mean_distance.mean() + args.outlier_std * mean_distance.std()
        xyz, rgb = xyz[inlier], rgb[inlier]
        tracks = [t for t, k in zip(tracks, inlier) if k]
    normals = pca_normals(xyz, args.neighbors)
    # Orient each normal towards the mean viewing direction of the cameras that saw the point.
    view = np.zeros_like(xyz)
    for i, track in enumerate(tracks):
        for image_id in np.unique(track):
            if image_id not in centers:
                fail(f"{args.model}/points3D.txt: track names image {image_id}, not in images.txt")
            d = centers[image_id] - xyz[i]
            view[i] += d / max(np.linalg.norm(d), 1e-12)
    flip = np.einsum("ni,ni->n", normals, view) < 0
    normals[flip] *= -1
    write_ply(args.out_ply, xyz, normals, rgb)
    print(f"{len(xyz)} points (of {n_total}; min track {args.min_track}"
          + (f", max error {args.max_error} px" if args.max_error > 0 else "")
          + (f", outliers beyond {args.outlier_std} std of the mean distance to "
             f"{args.outlier_neighbors} neighbours dropped" if args.outlier_std > 0 else "") + ")")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("list")
    p.add_argument("sparse")
    p.add_argument("image_dir")
    p.add_argument("out_list")
    p.set_defaults(run=cmd_list)
    p = sub.add_parser("prepare")
    p.add_argument("sparse")
    p.add_argument("database")
    p.add_argument("out_model")
    p.add_argument("--pairs", default="")
    p.add_argument("--neighbors", type=int, default=20)
    p.add_argument("--max-angle", type=float, default=60.0)
    p.set_defaults(run=cmd_prepare)
    p = sub.add_parser("export")
    p.add_argument("model")
    p.add_argument("out_ply")
    p.add_argument("--neighbors", type=int, default=12)
    p.add_argument("--min-track", type=int, default=2)
    p.add_argument("--max-error", type=float, default=0.0)
    p.add_argument("--outlier-std", type=float, default=2.0)
    p.add_argument("--outlier-neighbors", type=int, default=20)
    p.set_defaults(run=cmd_export)
    args = parser.parse_args()
    try:
        args.run(args)
    except InputError as e:
        print(f"known_poses.py: error: {e}", file=sys.stderr)
        sys.exit(1)
    except sqlite3.Error as e:
        print(f"known_poses.py: error: {getattr(args, 'database', '')}: sqlite: {e}",
              file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
