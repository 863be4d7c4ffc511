#!/usr/bin/env python3
"""Writes the seed archives of fuzz_service_upload next to this script: the hostile archives
the benchmark tests send (src/rephoto/service/server_test.cc, hostile_test.cc) and valid ones,
with a small valid PNG as the render. Run once; the outputs are committed."""
import io
import os
import struct
import tarfile
import zipfile
import zlib

here = os.path.dirname(os.path.abspath(__file__))


def png(width=8, height=6):
    """An RGBA PNG of width x height with a gradient."""
    rows = []
    for y in range(height):
        pixels = b"".join(bytes([(x * 30) % 256, (y * 40) % 256, 128, 255]) for x in range(width))
        rows.append(b"\0" + pixels)  # filter type 0

    def chunk(kind, data):
        return (struct.pack(">I", len(data)) + kind + data +
                struct.pack(">I", zlib.crc32(kind + data) & 0xffffffff))
    header = struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) +
            chunk(b"IDAT", zlib.compress(b"".join(rows))) + chunk(b"IEND", b""))


def tar(members, gz=False):
    out = io.BytesIO()
    with tarfile.open(fileobj=out, mode="w:gz" if gz else "w", format=tarfile.PAX_FORMAT,
                      encoding="utf-8", errors="surrogateescape") as archive:
        for name, kind, data in members:
            info = tarfile.TarInfo(name)
            info.type = kind
            if kind == tarfile.SYMTYPE or kind == tarfile.LNKTYPE:
                info.linkname = data.decode()
                data = b""
            info.size = len(data)
            archive.addfile(info, io.BytesIO(data))
    return out.getvalue()


def zipped(members):
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members:
            archive.writestr(name, data)
    return out.getvalue()


image = png()
reg = tarfile.REGTYPE
seeds = {
    "valid.tar": tar([("00.png", reg, image), ("03.png", reg, image)]),
    "valid_nested.tar": tar([("renders/", tarfile.DIRTYPE, b""), ("renders/00.PNG", reg, image)]),
    "valid.tar.gz": tar([("00.png", reg, image)], gz=True),
    "valid.zip": zipped([("00.png", image), ("03.jpg", b"\xff\xd8\xff\xe0")]),
    "traversal.tar": tar([("../../00.png", reg, image)]),
    "absolute.zip": zipped([("/tmp/00.png", image)]),
    "symlink.tar": tar([("00.png", tarfile.SYMTYPE, b"/etc/passwd")]),
    "hardlink.tar": tar([("00.png", tarfile.LNKTYPE, b"03.png")]),
    "device.tar": tar([("00.png", tarfile.CHRTYPE, b"")]),
    "fifo.tar": tar([("00.png", tarfile.FIFOTYPE, b"")]),
    "invalid_utf8_name.tar": tar([("\udcff\udcfe.png", reg, image)]),
    "control_name.zip": zipped([("0\x010.png", image)]),
    "backslash.zip": zipped([("..\\00.png", image)]),
    "duplicate_stem.tar": tar([("00.png", reg, image), ("x/00.exr", reg, image)]),
    "unknown_stem.tar": tar([("99.png", reg, image)]),
    "not_an_image.tar": tar([("03.png", reg, b"hello")]),
    "bomb.zip": zipped([("00.png", b"\0" * (8 << 20))]),
    "many_entries.tar": tar([(f"d{i}/", tarfile.DIRTYPE, b"") for i in range(80)]),
    "truncated.tar": tar([("00.png", reg, image)])[:700],
}
for name, data in seeds.items():
    with open(os.path.join(here, name), "wb") as f:
        f.write(data)
