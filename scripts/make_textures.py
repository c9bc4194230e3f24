#!/usr/bin/env python3
"""Writes the bitmap textures of mitsuba_scenes/bitmap.xml: textures/tiles.png, a 24x16
8-bit sRGB PNG of coloured tiles with thin dark seams and a smooth gradient (so the
filter, the wrap mode and the sRGB decoding all show), and textures/grain.exr, a 16x16
linear float32 RGB grain. Deterministic; needs numpy, and mitsuba for the EXR writer:
.venv/bin/python scripts/make_textures.py"""
import struct
import zlib

import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")
rng = np.random.default_rng(7)


def write_png(path, rgb8):
    """A plain 8-bit RGB PNG (no gamma chunk: sRGB by convention)."""
    h, w, _ = rgb8.shape
    raw = b"".join(b"\x00" + rgb8[y].tobytes() for y in range(h))
    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)
    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
    png += chunk(b"IDAT", zlib.compress(raw, 9)) + chunk(b"IEND", b"")
    open(path, "wb").write(png)


W, H = 24, 16
y, x = np.mgrid[0:H, 0:W]
tiles = rng.integers(60, 250, size=(H // 4, W // 4, 3))
img = tiles[y // 4, x // 4].astype(np.float64)
img *= (0.6 + 0.4 * x / (W - 1))[..., None]          # a gradient across
img[(x % 4 == 0) | (y % 4 == 0)] = [30, 25, 20]       # dark seams
write_png("mitsuba_scenes/textures/tiles.png", np.clip(img, 0, 255).astype(np.uint8))

grain = 0.15 + 0.7 * rng.random((16, 16, 3))
mi.Bitmap(grain.astype(np.float32), pixel_format=mi.Bitmap.PixelFormat.RGB).write("mitsuba_scenes/textures/grain.exr")
