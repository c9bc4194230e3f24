#!/usr/bin/env python3
"""Regenerates the values the tests take from Mitsuba 3 directly (not from renders):

  principled   prints, as Rust, the (f · |cos θ_o|, pdf) table of
               tests/principled.rs's `principled_matches_mitsuba_values`: Mitsuba's
               `BSDF::eval_pdf` of three `principled` plugins at four direction pairs
  jpeg         writes tests/fixtures/tiles_jpg_decoded_by_mitsuba.png: the texels
               Mitsuba decodes mitsuba_scenes/textures/tiles.jpg to (its libjpeg), stored
               losslessly (8-bit PNG), for tests/drop_in_plugins.rs's
               `jpeg_decodes_as_mitsuba`

Deterministic; the committed values are from Mitsuba 3.9.1 (scalar_rgb). Needs numpy
and mitsuba (python3 -m venv .venv && .venv/bin/pip install mitsuba numpy):
  .venv/bin/python scripts/mitsuba_fixtures.py principled
  .venv/bin/python scripts/mitsuba_fixtures.py jpeg [--out FILE]"""
import argparse
import math
import sys

import mitsuba as mi

mi.set_variant("scalar_rgb")

# tests/principled.rs's BSDFs, by Mitsuba's parameter names. Its `base()` (η 1.5,
# roughness 0.5) is Mitsuba's default `specular` 0.5 (η = 2 / (1 − √(0.08 s)) − 1).
BSDFS = [
    ("plastic", {
        "base_color": [0.8, 0.5, 0.2], "roughness": 0.4, "sheen": 0.8, "sheen_tint": 0.5,
        "clearcoat": 0.7, "clearcoat_gloss": 0.6, "spec_tint": 0.3, "flatness": 0.4,
        "specular": 0.6, "main_specular_sampling_rate": 0.8, "clearcoat_sampling_rate": 2.0,
    }),
    ("metal", {
        "base_color": [0.9, 0.75, 0.4], "metallic": 0.9, "roughness": 0.5,
        "anisotropic": 0.6,
    }),
    ("glass", {
        "base_color": [0.85, 0.95, 0.9], "spec_trans": 0.5, "eta": 1.45, "roughness": 0.3,
    }),
]


def normalize(x, y, z):
    n = math.sqrt(x * x + y * y + z * z)
    return [x / n, y / n, z / n]


# (wi, wo) in the local frame: front reflection, transmission, from inside out, and
# reflection inside (the test's `dirs`).
DIRS = [
    (normalize(0.5, 0.2, 0.8), normalize(-0.3, 0.4, 0.7)),
    (normalize(0.5, 0.2, 0.8), normalize(-0.2, -0.1, -0.9)),
    (normalize(0.3, -0.2, -0.7), normalize(-0.5, 0.3, 0.6)),
    (normalize(0.3, -0.2, -0.7), normalize(-0.4, 0.3, -0.7)),
]


def rgb(v):
    return {"type": "rgb", "value": v} if isinstance(v, list) else v


def principled():
    print(f"// Mitsuba {mi.__version__} ({mi.variant()}), scripts/mitsuba_fixtures.py principled")
    for name, params in BSDFS:
        bsdf = mi.load_dict({"type": "principled", **{k: rgb(v) for k, v in params.items()}})
        print(f'("{name}", [')
        for wi, wo in DIRS:
            si = mi.SurfaceInteraction3f()
            si.wi = mi.Vector3f(wi)
            si.uv = mi.Point2f(0, 0)
            f, pdf = bsdf.eval_pdf(mi.BSDFContext(), si, mi.Vector3f(wo))
            print(f"    ([{f[0]:.9}, {f[1]:.9}, {f[2]:.9}], {pdf:.9}),")
        print("]),")


def jpeg(out):
    b = mi.Bitmap("mitsuba_scenes/textures/tiles.jpg")
    # As loaded: 8-bit sRGB RGB, the decoder's bytes; PNG keeps them exactly.
    assert b.component_format() == mi.Struct.Type.UInt8, b
    b.write(out)
    print(f"wrote {out} ({b.width()}x{b.height()}, Mitsuba {mi.__version__})")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("what", choices=["principled", "jpeg"])
    ap.add_argument("--out", default="tests/fixtures/tiles_jpg_decoded_by_mitsuba.png")
    a = ap.parse_args()
    principled() if a.what == "principled" else jpeg(a.out)
    sys.exit(0)
