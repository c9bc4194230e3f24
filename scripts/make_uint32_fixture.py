#!/usr/bin/env python3
"""Mitsuba 3's own uint32 EXR, for tests/drop_in_rest.rs: a float image of chosen
values (negative, zero, tiny, ordinary, just below and above 1, large, and a ramp)
converted by Mitsuba's Bitmap to the uint32 component format, as an `hdrfilm` with
`component_format` uint32 stores its channels, and written by Mitsuba. Writes
tests/fixtures/film/uint32_input.exr (the float32 values) and uint32_mitsuba.exr (the
uint32 file), with their sha256 in uint32_mitsuba.json.

Run: .venv/bin/python scripts/make_uint32_fixture.py
"""

import hashlib
import json
from pathlib import Path

import mitsuba as mi
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "tests/fixtures/film"

mi.set_variant("scalar_rgb")
special = [-1.0, -1e-6, 0.0, 1e-10, 1e-6, 2.0 ** -9, 2.0 ** -8, 0.001, 0.1, 0.25, 1 / 3,
           0.5, 0.75, 0.999, 0.9999999, 1.0, 1.0000001, 1.5, 2.0, 1000.0]
w, h = 16, 8
n = w * h * 3
ramp = np.linspace(-0.1, 1.1, n - len(special))
values = np.concatenate([np.array(special), ramp]).astype(np.float32).reshape(h, w, 3)
OUT.mkdir(parents=True, exist_ok=True)
source = mi.Bitmap(values, mi.Bitmap.PixelFormat.RGB)
source.write(str(OUT / "uint32_input.exr"))
source.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt32, False).write(
    str(OUT / "uint32_mitsuba.exr"))
sha = {f: hashlib.sha256((OUT / f).read_bytes()).hexdigest()
       for f in ["uint32_input.exr", "uint32_mitsuba.exr"]}
(OUT / "uint32_mitsuba.json").write_text(json.dumps({
    "made_by": "scripts/make_uint32_fixture.py",
    "mitsuba_version": mi.__version__,
    "size": [w, h],
    "sha256": sha,
}, indent=2) + "\n")
print(sha)
