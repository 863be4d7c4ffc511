#!/usr/bin/env python3
"""Writes the seed inputs of fuzz_splat (fuzz/fuzz_splat.cc) next to this script: a selector
byte (0 PLY, 1 .splat, 2 cameras.json) followed by a small file of that format. Standard
library only: python3 make_seeds.py"""
import json
import math
import os
import struct

here = os.path.dirname(os.path.abspath(__file__))


def write(name, selector, payload):
    with open(os.path.join(here, name), "wb") as f:
        f.write(bytes([selector]) + payload)


def inria_ply(count, degree, normals):
    rest = 3 * ((degree + 1) ** 2 - 1)
    names = ["x", "y", "z"] + (["nx", "ny", "nz"] if normals else []) + \
        ["f_dc_0", "f_dc_1", "f_dc_2"] + [f"f_rest_{i}" for i in range(rest)] + \
        ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    header = "ply\nformat binary_little_endian 1.0\nelement vertex %d\n" % count
    header += "".join(f"property float {n}\n" for n in names) + "end_header\n"
    body = b""
    for g in range(count):
        values = {n: 0.1 * ((g + i) % 7) for i, n in enumerate(names)}
        values.update(x=0.2 * g - 0.3, y=0.1 * g, z=2.0 + g, opacity=1.0,
                      scale_0=math.log(0.2), scale_1=math.log(0.1), scale_2=math.log(0.05),
                      rot_0=1.0 + g)
        body += struct.pack("<%df" % len(names), *[values[n] for n in names])
    return header.encode() + body


def compressed_ply():
    chunk = [-1, -1, 1, 1, 1, 3, -3, -3, -3, -1, -1, -1, 0, 0, 0, 1, 1, 1]
    header = "ply\nformat binary_little_endian 1.0\nelement chunk 1\n"
    header += "".join(f"property float {n}\n" for n in [
        "min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x", "min_scale_y",
        "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z", "min_r", "min_g", "min_b",
        "max_r", "max_g", "max_b"])
    header += "element vertex 2\nproperty uint packed_position\nproperty uint packed_rotation\n"
    header += "property uint packed_scale\nproperty uint packed_color\nelement sh 2\n"
    header += "".join(f"property uchar f_rest_{i}\n" for i in range(9)) + "end_header\n"
    body = struct.pack("<18f", *chunk)
    body += struct.pack("<4I", 0x3FF7FBFF, 0x1FF7FDFF, 0x20100400, 0xFF8040C0)
    body += struct.pack("<4I", 0x40080200, 0x80000000, 0x7FFFFFFF, 0x10203040)
    body += bytes(range(0, 180, 10))
    return header.encode() + body


def splat():
    out = b""
    for g in range(3):
        out += struct.pack("<6f", 0.1 * g, 0, 2 + g, 0.1, 0.2, 0.05)
        out += bytes([200, 100, 50, 180, 128 + 100, 128, 128, 128 - 40])
    return out


write("inria_sh0", 0, inria_ply(3, 0, True))
write("inria_sh1", 0, inria_ply(2, 1, False))
write("compressed", 0, compressed_ply())
write("three.splat", 1, splat())
write("cameras_json", 2, json.dumps([{
    "id": 0, "img_name": "a", "width": 40, "height": 30, "position": [1, 2, 3],
    "rotation": [[0, 0, 1], [-1, 0, 0], [0, -1, 0]], "fy": 50.5, "fx": 50}]).encode())
