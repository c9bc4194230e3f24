#!/usr/bin/env python3
"""Writes tests/fixtures/sampler_counts_mitsuba.json: for each of Mitsuba 3's samplers,
the sample count it renders with when a file asks for `sample_count` = n (Mitsuba rounds
it up for stratified, multijitter, orthogonal and ldsampler), read back from the real
Mitsuba 3 (scalar_rgb: mi.load_dict(...).sample_count()). tests/drop_in_rest.rs checks
mediareg's rounding against these.

Usage: .venv/bin/python scripts/sampler_counts.py
"""
import json
import os

import mitsuba as mi

mi.set_variant("scalar_rgb")
mi.set_log_level(mi.LogLevel.Error)

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
COUNTS = list(range(1, 130)) + [255, 256, 257, 1000, 1024, 4096, 5000, 65536, 100000]


def main():
    out = {"mitsuba_version": mi.__version__, "variant": "scalar_rgb",
           "made_by": "scripts/sampler_counts.py", "counts": {}}
    for sampler in ["independent", "stratified", "multijitter", "orthogonal", "ldsampler"]:
        out["counts"][sampler] = [
            [n, mi.load_dict({"type": sampler, "sample_count": n}).sample_count()]
            for n in COUNTS
        ]
    with open(os.path.join(ROOT, "tests/fixtures/sampler_counts_mitsuba.json"), "w") as f:
        json.dump(out, f)
        f.write("\n")


if __name__ == "__main__":
    main()
