#!/usr/bin/python3
"""Evaluation copy of a COLMAP text model at a lower resolution (for checks by hand).

Usage: scale_scene.py SPARSE IMAGE_DIR SHORT_SIDE OUT
Writes OUT/sparse/{cameras,images,points3D}.txt with every camera scaled so that its shorter side
is SHORT_SIDE pixels (focal lengths and principal point times the size ratio per axis: exact for
COLMAP's convention that pixel (0,0)'s corner is the origin) and OUT/images/<stem>.png, the
photos of images.txt area-averaged (PIL box filter) to the same size, lossless, and
OUT/present.txt, the names whose photo exists (others are skipped with a message). Only camera
models without distortion or with radial terms that are resolution independent are accepted
(SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV). Needs python3-pil.
"""
import os
import shutil
import sys

from PIL import Image


def main():
    if len(sys.argv) != 5:
        sys.exit(__doc__)
    sparse, image_dir, short, out = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
    os.makedirs(os.path.join(out, "sparse"), exist_ok=True)
    os.makedirs(os.path.join(out, "images"), exist_ok=True)
    sizes, lines = {}, []
    for line in open(os.path.join(sparse, "cameras.txt"), encoding="utf-8"):
        w = line.split()
        if not w or w[0].startswith("#"):
            lines.append(line)
            continue
        width, height = int(w[2]), int(w[3])
        s = short / min(width, height)
        new_w, new_h = round(width * s), round(height * s)
        sx, sy = new_w / width, new_h / height
        p = [float(v) for v in w[4:]]
        if w[1] in ("SIMPLE_PINHOLE", "SIMPLE_RADIAL", "RADIAL"):  # f cx cy [k...]
            p[0] *= sx
            p[1] *= sx
            p[2] *= sy
        elif w[1] in ("PINHOLE", "OPENCV"):  # fx fy cx cy [k1 k2 p1 p2]
            p[0] *= sx
            p[1] *= sy
            p[2] *= sx
            p[3] *= sy
        else:
            sys.exit(f"scale_scene.py: error: {sparse}/cameras.txt: model {w[1]} not supported")
        sizes[w[0]] = (new_w, new_h)
        lines.append(f"{w[0]} {w[1]} {new_w} {new_h} " + " ".join(repr(v) for v in p) + "\n")
    with open(os.path.join(out, "sparse", "cameras.txt"), "w", encoding="utf-8") as f:
        f.writelines(lines)
    for name in ("images.txt", "points3D.txt"):
        shutil.copy(os.path.join(sparse, name), os.path.join(out, "sparse", name))
    image_lines = open(os.path.join(sparse, "images.txt"), encoding="utf-8").read().split("\n")
    present, missing = [], []
    i = 0
    while i < len(image_lines):
        line = image_lines[i].strip()
        i += 1
        if not line or line.startswith("#"):
            continue
        i += 1  # the 2D points line
        w = line.split(None, 9)
        dst = os.path.join(out, "images", os.path.splitext(w[9])[0] + ".png")
        os.makedirs(os.path.dirname(dst), exist_ok=True)
        if not os.path.isfile(os.path.join(image_dir, w[9])):
            missing.append(w[9])
            continue
        present.append(w[9])
        if not os.path.exists(dst):
            photo = Image.open(os.path.join(image_dir, w[9])).convert("RGB")
            photo.resize(sizes[w[8]], Image.BOX).save(dst)
    with open(os.path.join(out, "present.txt"), "w", encoding="utf-8") as f:
        f.writelines(name + "\n" for name in present)
    if missing:
        print(f"scale_scene.py: {len(missing)} image(s) without a photo skipped, e.g. "
              f"'{missing[0]}' (OUT/present.txt lists the others)", file=sys.stderr)


if __name__ == "__main__":
    main()
