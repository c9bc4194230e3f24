#!/usr/bin/env python3
"""Volumes of Mitsuba 3's volume-optimization tutorial scene (mitsuba_scenes/volume_opt/).

Writes, in Mitsuba's .vol format ("VOL", version 3, encoding 1 = float32, xres yres zres
channels as i32, a bounding box as 6 f32, then the values, x fastest, then y, then z):

* mitsuba_scenes/volume_opt/init_16.vol: the tutorial's initial grid, 16^3 voxels, one
  channel, every value 0.002 (always written; deterministic).
* with --reference SRC: mitsuba_scenes/volume_opt/reference.vol, the tutorial's
  reference density (mitsuba-tutorials scenes/volume.vol, 44 x 45 x 53, max 1.85) with the
  tutorial's rotation baked in. The tutorial places that grid with
      to_world = rotate([1, 0, 0], -90) @ scale(2) @ translate(-0.5)
  and the grid it optimizes with translate(-1) @ scale(2) (the same cube [-1, 1]^3, no
  rotation). Rotating by -90 degrees about x sends the grid's (u, v, w) in [0, 1]^3 to
  world (2u - 1, 2w - 1, 1 - 2v), so the baked grid's axes are X = u, Y = w, Z = 1 - v:
  a permutation and a flip of the voxels, which maps voxel centres onto voxel centres,
  so its trilinear lookups are those of the original exactly. Both grids then share one
  gridvolume to_world (scale 2, then translate -1), and the scene swaps them through
  $sigma_t_file. The file in the repository was made from the tutorials' commit a8dbee7
  (scenes/volume.vol, sha256 printed by this script):
      git -C MIRROR show HEAD:scenes/volume.vol > /tmp/volume.vol
      scripts/make_volume_opt.py --reference /tmp/volume.vol

Only numpy is needed. Usage: scripts/make_volume_opt.py [--reference SRC] [--out-dir DIR]
"""
import argparse
import hashlib
import struct
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT_DIR = ROOT / "mitsuba_scenes" / "volume_opt"
INIT_RES = 16
INIT_VALUE = 0.002


def write_vol(path, data, bbox=(-1.0, -1.0, -1.0, 1.0, 1.0, 1.0)):
    """data: array [z, y, x] or [z, y, x, c] (x fastest in the file)."""
    data = np.asarray(data, dtype=np.float32)
    if data.ndim == 3:
        data = data[..., None]
    zr, yr, xr, ch = data.shape
    with open(path, "wb") as f:
        f.write(b"VOL" + bytes([3]))
        f.write(struct.pack("<iiiii", 1, xr, yr, zr, ch))
        f.write(struct.pack("<6f", *bbox))
        f.write(np.ascontiguousarray(data).astype("<f4").tobytes())


def read_vol(path):
    b = Path(path).read_bytes()
    if b[:3] != b"VOL" or b[3] != 3:
        raise ValueError(f"{path}: not a version-3 .vol file")
    (enc,) = struct.unpack("<i", b[4:8])
    if enc != 1:
        raise ValueError(f"{path}: encoding {enc} (only 1, float32, is read)")
    xr, yr, zr, ch = struct.unpack("<4i", b[8:24])
    bbox = struct.unpack("<6f", b[24:48])
    data = np.frombuffer(b[48:], dtype="<f4").reshape(zr, yr, xr, ch)
    return data, bbox


def bake_rotation(data):
    """data[w][v][u] (the tutorial's grid, [z, y, x]) to new[Z][Y][X] with X = u,
    Y = w, Z = 1 - v (see the module's docstring)."""
    # new[Z, Y, X] = old[w = Y, v = n_v - 1 - Z, u = X]
    return np.ascontiguousarray(np.transpose(data, (1, 0, 2, 3))[::-1])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--reference", help="the tutorial's scenes/volume.vol to bake into reference.vol")
    ap.add_argument("--out-dir", default=str(OUT_DIR))
    a = ap.parse_args()
    out = Path(a.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    init = np.full((INIT_RES,) * 3, INIT_VALUE, dtype=np.float32)
    write_vol(out / "init_16.vol", init)
    print(f"wrote {out / 'init_16.vol'}: {INIT_RES}^3 at {INIT_VALUE}")
    if a.reference:
        src = Path(a.reference).read_bytes()
        data, bbox = read_vol(a.reference)
        baked = bake_rotation(data)
        write_vol(out / "reference.vol", baked)
        zr, yr, xr, _ = baked.shape
        print(f"read {a.reference} (sha256 {hashlib.sha256(src).hexdigest()}): "
              f"{data.shape[2]} x {data.shape[1]} x {data.shape[0]}, file bbox {bbox}")
        print(f"wrote {out / 'reference.vol'}: {xr} x {yr} x {zr}, mean {baked.mean():.4f}, "
              f"max {baked.max():.4f}, {(baked > 0).mean() * 100:.0f}% non-zero")


if __name__ == "__main__":
    main()
