#!/usr/bin/env python3
"""Writes the named conductor materials (`conductor`/`roughconductor` `material="Au"`, ...)
from the real Mitsuba 3 (pip package `mitsuba`):

  src/load/conductor_ior.txt
      the spectral tables Mitsuba 3 ships (its data/ior/NAME.{eta,k}.spd: luxpop.com
      data after Palik), one line per material and part, "NAME eta l1:v1, l2:v2, ...";
      a table identical to another's is written "NAME = OTHER". mediareg turns each into
      RGB at load as Mitsuba's RGB variants do (src/load/conductor_ior.rs).
  tests/fixtures/conductor_ior_mitsuba.json
      for every material, the RGB eta and k Mitsuba 3's scalar_rgb variant computes from
      them: a `conductor` with that material loaded and read back with mi.traverse
      (keys "eta.value", "k.value"). tests/drop_in_rest.rs checks mediareg against these.

Usage: .venv/bin/python scripts/conductor_ior.py
"""
import json
import os

import mitsuba as mi

mi.set_variant("scalar_rgb")

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
DATA = os.path.join(os.path.dirname(mi.__file__), "data", "ior")


def read_spd(path):
    """(wavelength, value) pairs of a Mitsuba .spd file; '#' lines are comments."""
    pairs = []
    with open(path) as f:
        for line in f:
            line = line.strip()
            if line and not line.startswith("#"):
                w, v = line.split()[:2]
                pairs.append((w, v))
    return pairs


def main():
    names = sorted({f.rsplit(".", 2)[0] for f in os.listdir(DATA) if f.endswith(".spd")})
    tables, lines, expected = {}, [], {}
    for name in names:
        parts = tuple(
            tuple(read_spd(os.path.join(DATA, f"{name}.{p}.spd"))) for p in ("eta", "k")
        )
        same = tables.get(parts)
        if same is not None:
            lines.append(f"{name} = {same}")
        else:
            tables[parts] = name
            for p, pairs in zip(("eta", "k"), parts):
                lines.append(f"{name} {p} " + ", ".join(f"{w}:{v}" for w, v in pairs))
        bsdf = mi.load_dict({"type": "conductor", "material": name})
        params = mi.traverse(bsdf)
        expected[name] = {
            "eta": [float(c) for c in params["eta.value"]],
            "k": [float(c) for c in params["k.value"]],
        }
    header = (
        "# Mitsuba 3's conductor IOR tables (data/ior/*.spd, luxpop.com after Palik), "
        f"Mitsuba {mi.__version__}; written by scripts/conductor_ior.py\n"
    )
    with open(os.path.join(ROOT, "src/load/conductor_ior.txt"), "w") as f:
        f.write(header + "\n".join(lines) + "\n")
    out = {
        "mitsuba_version": mi.__version__,
        "variant": "scalar_rgb",
        "made_by": "scripts/conductor_ior.py",
        "materials": expected,
    }
    with open(os.path.join(ROOT, "tests/fixtures/conductor_ior_mitsuba.json"), "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")
    print(f"{len(names)} materials, {len(tables)} distinct tables")


if __name__ == "__main__":
    main()
