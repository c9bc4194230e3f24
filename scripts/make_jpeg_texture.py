#!/usr/bin/env python3
"""Writes mitsuba_scenes/textures/tiles.jpg for bitmap_jpeg.xml: a 48x32 8-bit sRGB
image of coloured tiles, dark seams and a gradient, saved by Mitsuba 3's own JPEG writer
(libjpeg, quality 90, 4:2:0 chroma subsampling as most published JPEGs), so the test
also covers chroma upsampling. Deterministic; needs numpy and mitsuba:
.venv/bin/python scripts/make_jpeg_texture.py"""
import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")
rng = np.random.default_rng(11)
W, H = 48, 32
y, x = np.mgrid[0:H, 0:W]
tiles = rng.integers(50, 250, size=(H // 8, W // 8, 3))
img = tiles[y // 8, x // 8].astype(np.float64)
img *= (0.55 + 0.45 * x / (W - 1))[..., None]
img[(x % 8 == 0) | (y % 8 == 0)] = [35, 28, 22]
rgb8 = np.ascontiguousarray(np.clip(img, 0, 255).astype(np.uint8))
b = mi.Bitmap(rgb8, pixel_format=mi.Bitmap.PixelFormat.RGB)
b.write("mitsuba_scenes/textures/tiles.jpg", quality=90)
