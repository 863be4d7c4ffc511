#!/usr/bin/python3
"""Writes the small image fixtures of src/rephoto/io/image_io_test.cc.

PNG, EXR and PFM files are encoded here by hand (zlib + struct, no image library), so the test
checks rephoto's decoders against an independent encoder; the pixel values follow the formulas
below, which the C++ test recomputes. JPEG files are made with Pillow, and Pillow's decoded
pixels (libjpeg, default settings) are stored next to them as the reference.

Run: /usr/bin/python3 src/rephoto/io/testdata/make_fixtures.py   (writes into its own folder)

Not written here: leak_scanline.exr and short_tiles_attribute.exr, inputs found by
fuzz/fuzz_image.cc (kept as found).
"""
import os
import struct
import zlib

import numpy as np
from PIL import Image

HERE = os.path.dirname(os.path.abspath(__file__))
W, H = 5, 3  # odd sizes on purpose


def pattern8(x, y, c):
    return (x * 37 + y * 101 + c * 53 + 11) % 256


def pattern16(x, y, c):
    return (x * 9973 + y * 30011 + c * 4099 + 7) % 65536


def grid(channels, fn):
    return np.array([[[fn(x, y, c) for c in range(channels)] for x in range(W)]
                     for y in range(H)])


# ------------------------------------------------------------------------------------ PNG
def chunk(kind, data):
    return (struct.pack(">I", len(data)) + kind + data +
            struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))


def pack_row(samples, depth):
    """samples: 1-D list of ints for one row (all channels interleaved)."""
    if depth == 8:
        return bytes(samples)
    if depth == 16:
        return b"".join(struct.pack(">H", v) for v in samples)
    out, acc, bits = bytearray(), 0, 0
    for v in samples:
        acc = (acc << depth) | v
        bits += depth
        if bits == 8:
            out.append(acc)
            acc, bits = 0, 0
    if bits:
        out.append(acc << (8 - bits))
    return bytes(out)


ADAM7 = [(0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2),
         (0, 1, 1, 2)]


def write_png(name, pixels, color_type, depth, extra_chunks=(), interlace=False):
    """pixels: H x W x C integer array of stored samples (palette indices for type 3)."""
    h, w, _ = pixels.shape
    raw = bytearray()
    if not interlace:
        for y in range(h):
            raw += b"\x00" + pack_row(list(pixels[y].reshape(-1)), depth)  # filter 0 (None)
    else:
        for x0, y0, dx, dy in ADAM7:
            for y in range(y0, h, dy):
                xs = list(range(x0, w, dx))
                if not xs:
                    continue
                raw += b"\x00" + pack_row([int(v) for x in xs for v in pixels[y, x]], depth)
    ihdr = struct.pack(">IIBBBBB", w, h, depth, color_type, 0, 0, 1 if interlace else 0)
    data = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr)
    for kind, payload in extra_chunks:
        data += chunk(kind, payload)
    data += chunk(b"IDAT", zlib.compress(bytes(raw), 9)) + chunk(b"IEND", b"")
    with open(os.path.join(HERE, name), "wb") as f:
        f.write(data)
    return data


def make_pngs():
    write_png("grey8.png", grid(1, pattern8), 0, 8)
    write_png("grey16.png", grid(1, pattern16), 0, 16)
    write_png("grey1.png", grid(1, lambda x, y, c: (x + y) % 2), 0, 1)
    write_png("grey4.png", grid(1, lambda x, y, c: (x + 3 * y) % 16), 0, 4)
    write_png("grey_alpha8.png", grid(2, pattern8), 4, 8)
    write_png("grey_alpha16.png", grid(2, pattern16), 4, 16)
    write_png("rgb8.png", grid(3, pattern8), 2, 8)
    write_png("rgb16.png", grid(3, pattern16), 2, 16)
    write_png("rgba8.png", grid(4, pattern8), 6, 8)
    write_png("rgba16.png", grid(4, pattern16), 6, 16)
    write_png("rgb8_adam7.png", grid(3, pattern8), 2, 8, interlace=True)
    # Palette of 4 colours, index (x + y) % 4; entries 0 and 2 partly transparent.
    palette = [(255, 0, 0), (0, 255, 0), (0, 0, 255), (10, 20, 30)]
    plte = (b"PLTE", bytes(v for rgb in palette for v in rgb))
    indices = grid(1, lambda x, y, c: (x + y) % 4)
    write_png("palette.png", indices, 3, 8, [plte])
    write_png("palette2_trns.png", indices, 3, 2, [plte, (b"tRNS", bytes([0, 255, 128]))])
    # RGB with a transparent key colour: the colour of pixel (0, 0).
    rgb = grid(3, pattern8)
    key = b"".join(struct.pack(">H", int(v)) for v in rgb[0, 0])
    write_png("rgb8_trns.png", rgb, 2, 8, [(b"tRNS", key)])
    # Damaged files.
    good = open(os.path.join(HERE, "rgb8.png"), "rb").read()
    with open(os.path.join(HERE, "truncated.png"), "wb") as f:
        f.write(good[:len(good) - 30])  # cuts into the IDAT chunk
    bad = bytearray(good)
    idat = good.index(b"IDAT")
    bad[idat + 6] ^= 0xFF  # corrupts compressed data (and so the CRC)
    with open(os.path.join(HERE, "corrupt.png"), "wb") as f:
        f.write(bytes(bad))


# ------------------------------------------------------------------------------------ EXR
def attribute(name, kind, payload):
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(payload)) + payload


def write_exr(name, channels, values, pixel_type, window_min=(0, 0)):
    """channels: names sorted alphabetically; values: H x W x C floats, channel order as
    `channels`. pixel_type 1 = HALF, 2 = FLOAT. Uncompressed scanline file."""
    h, w, _ = values.shape
    chlist = b"".join(c.encode() + b"\0" + struct.pack("<iB3xii", pixel_type, 0, 1, 1)
                      for c in channels) + b"\0"
    x0, y0 = window_min
    box = struct.pack("<iiii", x0, y0, x0 + w - 1, y0 + h - 1)
    header = (b"\x76\x2f\x31\x01" + struct.pack("<I", 2) +
              attribute("channels", "chlist", chlist) +
              attribute("compression", "compression", b"\0") +
              attribute("dataWindow", "box2i", box) +
              attribute("displayWindow", "box2i", box) +
              attribute("lineOrder", "lineOrder", b"\0") +
              attribute("pixelAspectRatio", "float", struct.pack("<f", 1.0)) +
              attribute("screenWindowCenter", "v2f", struct.pack("<ff", 0, 0)) +
              attribute("screenWindowWidth", "float", struct.pack("<f", 1.0)) + b"\0")
    dtype = "<f2" if pixel_type == 1 else "<f4"
    chunks = []
    for y in range(h):
        line = b"".join(values[y, :, c].astype(dtype).tobytes() for c in range(len(channels)))
        chunks.append(struct.pack("<ii", y0 + y, len(line)) + line)
    offset = len(header) + 8 * h
    table = b""
    for c in chunks:
        table += struct.pack("<Q", offset)
        offset += len(c)
    with open(os.path.join(HERE, name), "wb") as f:
        f.write(header + table + b"".join(chunks))


def exr_value(x, y, c):
    return (x + 5 * y) * 0.25 + c - 2.0  # exact in half precision


def make_exrs():
    rgb = grid(3, exr_value).astype(np.float64)
    # File channel order is alphabetical: B, G, R.
    write_exr("half_rgb.exr", ["B", "G", "R"], rgb[:, :, ::-1], 1, window_min=(2, 3))
    rgba = grid(4, exr_value)
    write_exr("half_rgba.exr", ["A", "B", "G", "R"], rgba[:, :, [3, 2, 1, 0]], 1)
    y = grid(1, lambda x, y, c: x * 0.5 - y * 1.25 + 0.1).astype(np.float32)
    write_exr("float_y.exr", ["Y"], y, 2)


# ------------------------------------------------------------------------------------ PFM
def pfm_value(x, y, c):
    return x * 1.5 - y * 0.75 + c * 0.125 - 1.0


def write_pfm(name, values, big_endian):
    h, w, c = values.shape
    header = ("PF" if c == 3 else "Pf") + "\n%d %d\n%s\n" % (w, h, "1.0" if big_endian else "-1.0")
    data = values[::-1].astype(">f4" if big_endian else "<f4").tobytes()  # bottom row first
    with open(os.path.join(HERE, name), "wb") as f:
        f.write(header.encode() + data)


def make_pfms():
    write_pfm("rgb_big_endian.pfm", grid(3, pfm_value), True)
    write_pfm("grey_little_endian.pfm", grid(1, pfm_value), False)
    with open(os.path.join(HERE, "rgb_big_endian.pfm"), "rb") as f:
        good = f.read()
    with open(os.path.join(HERE, "truncated.pfm"), "wb") as f:
        f.write(good[:-7])


# ----------------------------------------------------------------------------------- JPEG
def make_jpegs():
    w, h = 19, 13
    x, y = np.meshgrid(np.arange(w), np.arange(h))
    rgb = np.stack([(x * 13 + y * 5) % 256, (x * 3 + y * 17 + 60) % 256,
                    (255 - x * 11 - y * 2) % 256], axis=-1).astype(np.uint8)
    Image.fromarray(rgb).save(os.path.join(HERE, "colour.jpg"), quality=90, subsampling=2)
    Image.fromarray(rgb[:, :, 1]).save(os.path.join(HERE, "grey.jpg"), quality=90)
    for name in ("colour.jpg", "grey.jpg"):
        decoded = np.asarray(Image.open(os.path.join(HERE, name)))
        if decoded.ndim == 2:
            decoded = decoded[:, :, None]
        with open(os.path.join(HERE, name.replace(".jpg", "_pillow.txt")), "w") as f:
            f.write("# Pillow %s decode of %s: width height channels, then values row by row\n"
                    % (Image.__version__, name))
            f.write("%d %d %d\n" % (decoded.shape[1], decoded.shape[0], decoded.shape[2]))
            for row in decoded:
                f.write(" ".join(str(v) for v in row.reshape(-1)) + "\n")
    good = open(os.path.join(HERE, "colour.jpg"), "rb").read()
    with open(os.path.join(HERE, "truncated.jpg"), "wb") as f:
        sos = good.index(b"\xff\xda")
        f.write(good[:(sos + len(good)) // 2])  # cuts the entropy-coded scan in half
    with open(os.path.join(HERE, "not_an_image.png"), "w") as f:
        f.write("this is a text file with an image extension\n")


def make_real_photo_samples():
    """Pillow's pixels at a few positions of a real photo from ../shared/data."""
    photo = os.path.join(HERE, "../../../../../shared/data/bundler_kermit/kermit000.jpg")
    if not os.path.exists(photo):
        return
    rgb = np.asarray(Image.open(photo).convert("RGB"))
    rng = np.random.default_rng(2017)
    with open(os.path.join(HERE, "kermit000_pillow_samples.txt"), "w") as f:
        f.write("# Pillow %s decode of shared/data/bundler_kermit/kermit000.jpg (%dx%d): x y r g b\n"
                % (Image.__version__, rgb.shape[1], rgb.shape[0]))
        points = [(0, 0), (rgb.shape[1] - 1, rgb.shape[0] - 1)] + [
            (int(rng.integers(rgb.shape[1])), int(rng.integers(rgb.shape[0]))) for _ in range(30)]
        for x, y in points:
            f.write("%d %d %d %d %d\n" % ((x, y) + tuple(int(v) for v in rgb[y, x])))


def make_reduced_jpeg_references():
    """Pillow's reduced decodes (draft mode: libjpeg's DCT scaling) of a real photo at 1/8 and 1/4
    (1/2 is not kept: 0.7 MB of text): the reference of io::ReadImagePreview."""
    photo = os.path.join(HERE, "../../../../../shared/data/bundler_kermit/kermit000.jpg")
    if not os.path.exists(photo):
        return
    for w, h in ((80, 60), (160, 120)):
        im = Image.open(photo)
        im.draft("RGB", (w, h))
        rgb = np.asarray(im.convert("RGB"))
        assert rgb.shape == (h, w, 3), rgb.shape
        with open(os.path.join(HERE, "kermit000_pillow_draft_%d.txt" % w), "w") as f:
            f.write("# Pillow %s draft-mode decode of shared/data/bundler_kermit/kermit000.jpg "
                    "at %dx%d: width height channels, then values row by row\n"
                    % (Image.__version__, w, h))
            f.write("%d %d %d\n" % (w, h, 3))
            for row in rgb:
                f.write(" ".join(str(v) for v in row.reshape(-1)) + "\n")


if __name__ == "__main__":
    make_pngs()
    make_exrs()
    make_pfms()
    make_jpegs()
    make_real_photo_samples()
    make_reduced_jpeg_references()
