#!/usr/bin/env python3
"""Writes tests/fixtures/transforms.json: for each snippet of operations inside
<transform name="to_world">, the 4x4 to_world matrix that the real Mitsuba 3 parser
builds from it. tests/parser.rs checks mediareg's XML loader against these matrices.

Each snippet is placed in a `rectangle` shape of a minimal scene. The recorded matrix is
the `to_world` property exactly as Mitsuba's XML parser produced it, in double precision
(mi.parser.parse_string -> SceneNode.props["to_world"], an AffineTransform4d in 3.9).
Cross-checks: the same scene loads with mi.load_string and mi.traverse gives the same
matrix (float32, so within 1e-6); for rigid snippets the to_world of a `perspective`
sensor agrees too (the sensor refuses scale factors).

Note: since Mitsuba 3.9 transforms are *affine*: a <matrix> whose bottom row is not
(0, 0, 0, 1) has that row dropped by the parser (case "matrix_16_projective").

Usage: .venv/bin/python scripts/transform_fixtures.py
"""
import json
import os

import mitsuba as mi
import numpy as np

VARIANT = "scalar_rgb"
mi.set_variant(VARIANT)

# (name, ops). Angles are degrees, as in Mitsuba's XML.
CASES = [
    # translate
    ("translate_value", '<translate value="1, -2, 3.5"/>'),
    ("translate_value_spaces", '<translate value="0.25 0.5 -0.75"/>'),
    ("translate_xyz", '<translate x="0.5" y="-1" z="-4"/>'),
    ("translate_x_only", '<translate x="3"/>'),
    ("translate_single_value_broadcast", '<translate value="1.5"/>'),
    # rotate
    ("rotate_value_axis_y30", '<rotate value="0, 1, 0" angle="30"/>'),
    ("rotate_x_attr_neg90", '<rotate x="1" angle="-90"/>'),
    ("rotate_y_attr_45", '<rotate y="1" angle="45"/>'),
    ("rotate_z_attr_120", '<rotate z="1" angle="120"/>'),
    ("rotate_xyz_attrs", '<rotate x="0.2" y="0.3" z="0.9" angle="33"/>'),
    ("rotate_unnormalized_002", '<rotate value="0, 0, 2" angle="90"/>'),
    ("rotate_unnormalized_110", '<rotate value="1, 1, 0" angle="45"/>'),
    ("rotate_unnormalized_110_attrs", '<rotate x="1" y="1" angle="60"/>'),
    ("rotate_angle_0", '<rotate value="1, 2, 3" angle="0"/>'),
    ("rotate_angle_270", '<rotate value="0, 0, 1" angle="270"/>'),
    # scale
    ("scale_uniform", '<scale value="2.5"/>'),
    ("scale_xyz", '<scale x="2" y="3" z="0.5"/>'),
    ("scale_x_only", '<scale x="4"/>'),
    ("scale_value_vector", '<scale value="1, 2, 3"/>'),
    ("scale_negative", '<scale value="-1, 1, 1"/>'),
    # matrix
    ("matrix_16", '<matrix value="1 2 3 4  0 1 0 5  0 0 2 6  0 0 0 1"/>'),
    ("matrix_16_commas",
     '<matrix value="0.5, 0, 0, 1, 0, 0.5, 0, 2, 0, 0, 0.5, 3, 0, 0, 0, 1"/>'),
    ("matrix_9_linear", '<matrix value="0 -1 0  1 0 0  0 0 2"/>'),
    ("matrix_16_projective", '<matrix value="1 0 0 0  0 1 0 0  0 0 1 0  0.1 0.2 0.3 1"/>'),
    # lookat
    ("lookat_up", '<lookat origin="0, 1, 5" target="0, 1, 0" up="0, 1, 0"/>'),
    ("lookat_up_oblique", '<lookat origin="1, 2, 3" target="-1, 0.5, 0" up="0, 0, 1"/>'),
    ("lookat_up_unnormalized", '<lookat origin="3, 3, 3" target="0, 0, 0" up="0, 5, 0"/>'),
    ("lookat_default_up", '<lookat origin="1, 2, 3" target="0, 0, 0"/>'),
    ("lookat_zero_up", '<lookat origin="0, 0, 0" target="0, 0, -1" up="0, 0, 0"/>'),
    ("lookat_default_up_neg_z", '<lookat origin="0, 0, 0" target="0.3, -0.2, -1"/>'),
    # compositions (each operation is applied after the previous ones)
    ("rotate_translate_lookat",
     '<rotate y="1" angle="20"/><translate x="1" y="2"/>'
     '<lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/>'),
    ("lookat_then_translate",
     '<lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/><translate x="1" y="2"/>'),
    ("scale_rotate_translate",
     '<scale x="0.3" y="0.6" z="0.3"/><rotate y="1" angle="20"/>'
     '<translate x="-0.35" y="-0.4" z="-0.3"/>'),
    ("translate_then_scale", '<translate x="1"/><scale value="2"/>'),
    ("translate_then_rotate", '<translate value="1, 0, 0"/><rotate z="1" angle="90"/>'),
    ("matrix_then_rotate_unnormalized",
     '<matrix value="1 0 0 1  0 1 0 2  0 0 1 3  0 0 0 1"/><rotate value="0, 2, 0" angle="30"/>'),
    ("rotate_rotate", '<rotate x="1" angle="30"/><rotate z="1" angle="60"/>'),
]


def shape_xml(ops):
    return ('<scene version="3.0.0"><shape type="rectangle" id="r">'
            f'<transform name="to_world">{ops}</transform></shape></scene>')


def parsed_matrix(ops):
    """The to_world property as the XML parser builds it (double precision)."""
    state = mi.parser.parse_string(mi.parser.ParserConfig(VARIANT), shape_xml(ops))
    (node,) = [n for n in state.nodes if n.props.id() == "r"]
    return np.array(node.props["to_world"].matrix, dtype=np.float64)


def shape_matrix(ops):
    """The to_world of the instantiated shape (float32 in scalar_rgb)."""
    scene = mi.load_string(shape_xml(ops))
    return np.array(mi.traverse(scene)["r.to_world"].matrix, dtype=np.float64)


def sensor_matrix(ops):
    xml = ('<scene version="3.0.0"><sensor type="perspective" id="s">'
           f'<transform name="to_world">{ops}</transform></sensor></scene>')
    scene = mi.load_string(xml)
    return np.array(scene.sensors()[0].world_transform().matrix, dtype=np.float64)


def main():
    out = {
        "mitsuba_version": mi.__version__,
        "variant": VARIANT,
        "source": "scripts/transform_fixtures.py: mi.parser.parse_string(...) node props['to_world'] "
                  "of a rectangle (double precision), cross-checked with mi.traverse",
        "cases": [],
    }
    names = set()
    for name, ops in CASES:
        assert name not in names, name
        names.add(name)
        m = parsed_matrix(ops)
        f = shape_matrix(ops)
        assert np.allclose(m, f, rtol=1e-6, atol=1e-6), (name, m, f)
        lin = m[:3, :3]
        if np.allclose(lin.T @ lin, np.eye(3), atol=1e-6) and np.allclose(m[3], [0, 0, 0, 1]):
            # Rigid transforms only: the perspective sensor refuses scale factors.
            s = sensor_matrix(ops)
            assert np.allclose(m, s, rtol=1e-6, atol=1e-6), (name, m, s)
        out["cases"].append({"name": name, "xml": ops, "matrix": m.tolist()})
    path = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests",
                        "fixtures", "transforms.json")
    with open(path, "w") as f:
        json.dump(out, f, indent=1)
        f.write("\n")
    print(f"wrote {len(out['cases'])} cases to {os.path.normpath(path)} "
          f"(Mitsuba {mi.__version__}, {VARIANT})")


if __name__ == "__main__":
    main()
