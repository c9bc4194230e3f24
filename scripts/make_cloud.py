#!/usr/bin/env python3
"""Write mitsuba_scenes/volumes/cloud.vol: a 64^3 cloud density in Mitsuba's .vol format.

The density is a smooth blob (an ellipsoid that falls off to 0 at its rim) carved by
fractal value noise (4 octaves of trilinearly interpolated random lattices, seed 5),
clamped to [0, 1]. Deterministic: the same file every run. Only numpy is needed.

Usage: scripts/make_cloud.py [OUT]   (default mitsuba_scenes/volumes/cloud.vol)
"""
import struct
import sys

import numpy as np

N = 64


def value_noise(rng, n, cells):
    """A lattice of cells^3 random values, trilinearly interpolated to n^3."""
    lat = rng.random((cells + 1,) * 3)
    x = np.linspace(0, cells, n, endpoint=False) + 0.5 * cells / n
    i = np.minimum(x.astype(int), cells - 1)
    f = x - i
    f = f * f * (3 - 2 * f)  # smoothstep: no creases at lattice planes
    out = 0
    for dz in (0, 1):
        wz = (f if dz else 1 - f)[:, None, None]
        for dy in (0, 1):
            wy = (f if dy else 1 - f)[None, :, None]
            for dx in (0, 1):
                wx = (f if dx else 1 - f)[None, None, :]
                v = lat[np.ix_(i + dz, i + dy, i + dx)]
                out = out + wz * wy * wx * v
    return out


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "mitsuba_scenes/volumes/cloud.vol"
    rng = np.random.default_rng(5)
    noise = sum(value_noise(rng, N, 2 ** (k + 2)) * 0.5 ** k for k in range(4)) / 1.875
    c = (np.arange(N) + 0.5) / N - 0.5
    z, y, x = np.meshgrid(c, c, c, indexing="ij")  # data is z-major, x fastest
    # An ellipsoid flattened at the bottom, as cumulus are.
    r = np.sqrt((x / 0.45) ** 2 + (y / 0.38) ** 2 + (z / 0.42) ** 2)
    r = np.where(y < -0.2, np.maximum(r, 1.0 + (-0.2 - y) * 8), r)
    density = np.clip((1.0 - r) * 2.5 + (noise - 0.5) * 1.6, 0.0, 1.0).astype(np.float32)
    with open(out, "wb") as f:
        f.write(b"VOL" + bytes([3]))
        f.write(struct.pack("<iiiii", 1, N, N, N, 1))
        f.write(struct.pack("<6f", 0, 0, 0, 1, 1, 1))
        f.write(density.tobytes())
    print(f"wrote {out}: {N}^3, mean {density.mean():.3f}, max {density.max():.3f}, "
          f"{(density > 0).mean() * 100:.0f}% non-zero")


if __name__ == "__main__":
    main()
