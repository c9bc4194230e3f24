#!/usr/bin/env python3
"""Write the inputs of the grid-medium adjoint test (mitsuba_scenes/grid_adjoint.xml).

All 8^3, one channel, Mitsuba's binary .vol format ("VOL", version 3, encoding 1 =
float32, xres yres zres channels as int32, bbox as 6 float32, then the values with x
fastest, then y, then z), bbox the unit cube. Deterministic: the same bytes every run.

mitsuba_scenes/volumes/
  grid_adjoint_sigma_t.vol  density in [0, 1]: a smooth anisotropic Gaussian blob
                            (0.1 + 0.9 exp(-r^2 / 2), widths 0.15, 0.13, 0.15 of the
                            box) faded out by a smoothstep towards the (0, 0, 0) corner
                            so that the 10 voxels with i + j + k <= 2 are exactly 0 (25
                            more are below 0.04); normalised so that its single largest
                            voxel is exactly 1. With scale 4 the optical depth through
                            the box is ~0.3 at the rim to ~3.6 through the core.
  grid_adjoint_albedo.vol   albedo in [0.5, 0.95] (both ends reached), smooth.
  grid_adjoint_v_smooth.vol direction field: a smooth product of sinusoids in [-1, 1],
  grid_adjoint_v_box.vol    direction field: 1 on the 3x3x3 box of voxels [3, 5]^3
                            (the dense core, the density's maximum inside), 0 elsewhere,
  grid_adjoint_v_noise.vol  direction field: white noise, uniform in [-1, 1]
                            (numpy default_rng(2024)),
                            each direction field multiplied by the taper
                            t = min(1, density / 0.04), so that it is 0 on the 10 empty
                            voxels and |h V| <= density / 2 for h <= 0.02: the sigma_t
                            grid stays >= 0 at x - hV, which Mitsuba's delta tracking
                            needs for an unbiased finite difference (the taper is 1
                            wherever density >= 0.04, on all of the box).
mitsuba_scenes/grid_adjoint_A.exr
                            the adjoint image, 32x24 RGB float32,
                            A(x, y, c) = (1 + 0.5 sin(0.3 x + 0.2 y + c)) / (32 * 24)
                            for pixel column x, row y, channel c (written with
                            mi.Bitmap; mitsuba_scenes/*.exr is git-ignored, so rerun this
                            script to get it back).

Usage: .venv/bin/python scripts/make_grid_adjoint.py   (numpy; mitsuba for the .exr)
"""
import struct
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
N = 8
W, H = 32, 24
TAPER = 0.04  # density below which the direction fields are scaled down


def write_vol(path, data):
    data = np.ascontiguousarray(data, dtype=np.float32)  # indexed [z, y, x]
    assert data.shape == (N, N, N)
    with open(path, "wb") as f:
        f.write(b"VOL" + bytes([3]))
        f.write(struct.pack("<iiiii", 1, N, N, N, 1))
        f.write(struct.pack("<6f", 0, 0, 0, 1, 1, 1))
        f.write(data.tobytes())


def fields():
    c = (np.arange(N) + 0.5) / N
    z, y, x = np.meshgrid(c, c, c, indexing="ij")  # data is z-major, x fastest
    k, j, i = np.meshgrid(np.arange(N), np.arange(N), np.arange(N), indexing="ij")

    # Density: an anisotropic Gaussian blob on a floor of 0.1, faded out towards the
    # origin corner.
    r2 = ((x - 0.57) / 0.15) ** 2 + ((y - 0.53) / 0.13) ** 2 + ((z - 0.48) / 0.15) ** 2
    blob = 0.1 + 0.9 * np.exp(-0.5 * r2)
    s = x + y + z  # 3/16 + (i + j + k) / 8 at the voxel centres
    f = np.clip((s - 0.45) / 0.75, 0.0, 1.0)
    fade = f * f * (3 - 2 * f)  # smoothstep: 0 exactly for i + j + k <= 2
    density = (blob * fade).astype(np.float64)
    density /= density.max()
    density = density.astype(np.float32)
    density[density == density.max()] = 1.0
    assert (density == 0).sum() == 10 and ((i + j + k <= 2) == (density == 0)).all()
    assert (density == 1.0).sum() == 1

    # Albedo: smooth, spanning [0.5, 0.95].
    a = np.sin(2.1 * x + 1.3) * np.cos(1.7 * y - 0.4) + 0.5 * np.sin(2.9 * z + 0.7)
    a = (a - a.min()) / (a.max() - a.min())
    albedo = (0.5 + 0.45 * a).astype(np.float32)

    taper = np.minimum(1.0, density.astype(np.float64) / TAPER)
    smooth = np.sin(np.pi * (1.1 * x + 0.7 * y) + 0.4) * np.cos(np.pi * (0.9 * z - 0.3 * x) - 0.2)
    box = ((i >= 3) & (i <= 5) & (j >= 3) & (j <= 5) & (k >= 3) & (k <= 5)).astype(np.float64)
    noise = np.random.default_rng(2024).uniform(-1.0, 1.0, size=(N, N, N))
    v = {name: (field * taper).astype(np.float32)
         for name, field in (("smooth", smooth), ("box", box), ("noise", noise))}
    v["zero"] = (density == 0).astype(np.float32)
    assert (taper[box > 0] == 1).all()
    return density, albedo, v


def adjoint_image():
    y, x = np.meshgrid(np.arange(H), np.arange(W), indexing="ij")
    a = np.stack([(1 + 0.5 * np.sin(0.3 * x + 0.2 * y + c)) / (W * H) for c in range(3)], -1)
    return a.astype(np.float32)  # [row, column, channel]


def main():
    vol = ROOT / "mitsuba_scenes" / "volumes"
    vol.mkdir(parents=True, exist_ok=True)
    density, albedo, v = fields()
    write_vol(vol / "grid_adjoint_sigma_t.vol", density)
    write_vol(vol / "grid_adjoint_albedo.vol", albedo)
    for name, field in v.items():
        write_vol(vol / f"grid_adjoint_v_{name}.vol", field)
    # Optical depth along z columns of voxels (x scale 4 and the [-1, 1] world size
    # 2): a rough guide to the scene's thickness.
    tau = 4 * 2 * density.mean(axis=0)
    print(f"sigma_t: mean {density.mean():.3f}, max {density.max()}, "
          f"{(density == 0).sum()} zero voxels, {(density < TAPER).sum()} below {TAPER}, "
          f"optical depth along z {tau.min():.2f} to {tau.max():.2f} (scale 4)")
    print(f"albedo: [{albedo.min():.3f}, {albedo.max():.3f}]")
    for name, field in v.items():
        print(f"v_{name}: [{field.min():.3f}, {field.max():.3f}], sum {field.sum():.3f}")

    import drjit as dr
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    dr.set_thread_count(1)
    a = adjoint_image()
    out = ROOT / "mitsuba_scenes" / "grid_adjoint_A.exr"
    # Mitsuba 3.9.1's EXR reader and writer hang with a one-thread pool: two threads
    # for the (tiny) write and read-back.
    dr.set_thread_count(2)
    mi.Bitmap(a, mi.Bitmap.PixelFormat.RGB).write(str(out))
    back = np.array(mi.Bitmap(str(out)), dtype=np.float32)
    dr.set_thread_count(1)
    assert back.shape == (H, W, 3) and np.array_equal(back, a), back.shape
    print(f"wrote {out}: {W}x{H} RGB, sum {a.sum(dtype=np.float64):.4f}")


if __name__ == "__main__":
    sys.exit(main())
