#!/usr/bin/env python3
"""Writes the seed corpora of the COLMAP and transforms.json fuzz targets
(fuzz/fuzz_scene_colmap.cc, fuzz/fuzz_scene_transforms_json.cc): small valid inputs from which
libFuzzer mutates.

colmap seeds: first byte = reader (0 cameras.txt, 1 images.txt, 2 points3D.txt, 3 cameras.bin,
4 images.bin, 5 points3D.bin, 6 the three text files separated by NUL bytes).
Usage: /usr/bin/python3 make_scene_seeds.py   (writes ./scene_colmap/* and ./scene_transforms_json/*)
"""
import json
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))

CAMERAS = "# c\n1 PINHOLE 640 480 500 510 320 240\n3 OPENCV_FISHEYE 800 600 300 301 400 300 0.01 0 0 0\n"
IMAGES = ("7 1 0 0 0 0 0 5 1 a.jpg\n100.5 200.25 -1 320 240 11\n"
          "2 0.70710678118654752 0 0.70710678118654752 0 1 2 3 3 b.png\n\n")
POINTS = "11 0 0 1 255 128 0 0.5 7 1\n12 1 2 3 1 2 3 -1\n"


def cameras_bin():
    out = struct.pack("<Q", 1)
    out += struct.pack("<IiQQ", 1, 2, 640, 480) + struct.pack("<4d", 500, 320, 240, -0.01)
    return out


def images_bin():
    out = struct.pack("<Q", 1)
    out += struct.pack("<I7dI", 7, 1, 0, 0, 0, 0, 0, 5, 1) + b"a.jpg\0"
    out += struct.pack("<Q", 2) + struct.pack("<2dQ", 100.5, 200.25, 2**64 - 1)
    out += struct.pack("<2dQ", 320, 240, 11)
    return out


def points_bin():
    out = struct.pack("<Q", 1)
    out += struct.pack("<Q3d3BdQ", 11, 0, 0, 1, 255, 128, 0, 0.5, 1) + struct.pack("<II", 7, 1)
    return out


def write(folder, name, data):
    os.makedirs(os.path.join(HERE, folder), exist_ok=True)
    with open(os.path.join(HERE, folder, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


write("scene_colmap", "cameras_txt", b"\0" + CAMERAS.encode())
write("scene_colmap", "images_txt", b"\1" + IMAGES.encode())
write("scene_colmap", "points3d_txt", b"\2" + POINTS.encode())
write("scene_colmap", "cameras_bin", b"\3" + cameras_bin())
write("scene_colmap", "images_bin", b"\4" + images_bin())
write("scene_colmap", "points3d_bin", b"\5" + points_bin())
write("scene_colmap", "model_txt", b"\6" + "\0".join([CAMERAS, IMAGES, POINTS]).encode())

identity = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]]
write("scene_transforms_json", "nerf_synthetic.json", json.dumps({
    "camera_angle_x": 0.6911112070083618,
    "frames": [{"file_path": "./train/r_0", "rotation": 0.0126, "transform_matrix": identity}]}))
write("scene_transforms_json", "instant_ngp.json", json.dumps({
    "fl_x": 1375.52, "fl_y": 1374.49, "cx": 554.558, "cy": 965.268, "w": 1080.0, "h": 1920.0,
    "k1": 0.0578421, "k2": -0.0805099, "p1": -0.000980296, "p2": 0.00015575, "aabb_scale": 4,
    "frames": [{"file_path": "images/0001.jpg", "sharpness": 31.7, "transform_matrix": identity},
               {"file_path": "images/0002.jpg", "fl_x": 1000, "camera_model": "OPENCV_FISHEYE",
                "p1": 0, "p2": 0, "k3": 0.001, "mask_path": "m.png", "transform_matrix": identity}]}))
