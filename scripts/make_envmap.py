#!/usr/bin/env python3
"""Writes mitsuba_scenes/textures/sky.exr, the environment map of mitsuba_scenes/envmap.xml:
a 64x32 latitude-longitude sky (blue above, brown ground below the horizon) with a small
bright sun, linear float32 RGB. Deterministic; needs numpy and mitsuba (for the EXR
writer): .venv/bin/python scripts/make_envmap.py"""
import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")
W, H = 64, 32
theta = (np.arange(H) / (H - 1))[:, None] * np.pi          # row y: theta = y / (H - 1) * pi
phi = ((np.arange(W) + 0.5) / W)[None, :] * 2 * np.pi       # column x: u = (x + 1/2) / W
up = np.cos(theta) * np.ones_like(phi)
sky = np.stack([0.3 + 0.2 * up, 0.45 + 0.25 * up, 0.9 + 0.3 * up], axis=-1)
ground = np.stack([0.25, 0.18, 0.1] * np.ones((1, 1, 3)), axis=-1).reshape(1, 1, 3) * np.ones((H, W, 3))
img = np.where(up[..., None] > 0, sky, ground)
# The sun: direction (theta 0.9, phi 2.0), a Gaussian blob about 0.12 rad wide.
d = np.stack([np.sin(phi) * np.sin(theta), np.cos(theta) * np.ones_like(phi), -np.cos(phi) * np.sin(theta)], -1)
s = np.array([np.sin(2.0) * np.sin(0.9), np.cos(0.9), -np.cos(2.0) * np.sin(0.9)])
img += np.exp(-np.arccos(np.clip(d @ s, -1, 1)) ** 2 / (2 * 0.12 ** 2))[..., None] * np.array([40.0, 36.0, 30.0])
mi.Bitmap(img.astype(np.float32), pixel_format=mi.Bitmap.PixelFormat.RGB).write("mitsuba_scenes/textures/sky.exr")
