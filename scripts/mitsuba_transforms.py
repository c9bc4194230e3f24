#!/usr/bin/env python3
"""Writes tests/fixtures/mitsuba_transforms.json: for each <transform> snippet, the 4x4
to_world matrix that the real Mitsuba 3 builds from it (read back with mi.traverse from a
`rectangle` shape). tests/xml_loader.rs checks mediareg's parser against these.

Usage: .venv/bin/python scripts/mitsuba_transforms.py
"""
import json
import os

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")

CASES = {
    "translate_value": '<translate value="1, -2, 3.5"/>',
    "translate_xyz": '<translate x="0.5" z="-4"/>',
    "rotate_value_axis": '<rotate value="0, 1, 0" angle="30"/>',
    "rotate_x": '<rotate x="1" angle="-90"/>',
    "rotate_unnormalized_z2": '<rotate value="0, 0, 2" angle="90"/>',
    "rotate_unnormalized_110": '<rotate x="1" y="1" angle="45"/>',
    "scale_uniform": '<scale value="2.5"/>',
    "scale_xyz": '<scale x="2" y="3" z="0.5"/>',
    "scale_value_vector": '<scale value="1, 2, 3"/>',
    "matrix": '<matrix value="1 2 3 4  0 1 0 5  0 0 2 6  0 0 0 1"/>',
    "matrix_3x3": '<matrix value="0 -1 0  1 0 0  0 0 2"/>',
    "lookat_default_up": '<lookat origin="1, 2, 3" target="0, 0, 0"/>',
    "lookat_zero_up": '<lookat origin="0, 0, 0" target="0, 0, -1" up="0, 0, 0"/>',
    "lookat_up": '<lookat origin="0, 1, 5" target="0, 1, 0" up="0, 1, 0"/>',
    "rotate_translate_lookat": '<rotate y="1" angle="20"/><translate x="1" y="2"/>'
    '<lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/>',
    "scale_rotate_translate": '<scale x="0.3" y="0.6" z="0.3"/><rotate y="1" angle="20"/>'
    '<translate x="-0.35" y="-0.4" z="-0.3"/>',
    "translate_then_scale": '<translate x="1"/><scale value="2"/>',
}


def main():
    out = {"mitsuba_version": mi.__version__, "variant": "scalar_rgb", "cases": []}
    for name, ops in CASES.items():
        xml = (f'<scene version="3.0.0"><shape type="rectangle" id="r">'
               f'<transform name="to_world">{ops}</transform></shape></scene>')
        scene = mi.load_string(xml)
        m = np.array(mi.traverse(scene)["r.to_world"].matrix, dtype=np.float64)
        out["cases"].append({"name": name, "ops": ops, "matrix": m.tolist()})
    path = os.path.join(os.path.dirname(__file__), "..", "tests", "fixtures", "mitsuba_transforms.json")
    with open(path, "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")
    print(f"wrote {len(out['cases'])} cases to {os.path.normpath(path)}")


if __name__ == "__main__":
    main()
