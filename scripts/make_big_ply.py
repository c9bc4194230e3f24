#!/usr/bin/env python3
"""Writes a displaced sphere of about N triangles as a binary little-endian PLY (float
x y z, uchar/int face lists) and a scene that renders it, for measuring mesh loading.

    scripts/make_big_ply.py 5000000 /tmp/big5m     # /tmp/big5m.ply, /tmp/big5m.xml
    scripts/make_big_ply.py 1000000 /tmp/big1m --obj   # also /tmp/big1m.obj (+ _obj.xml)

Needs numpy (e.g. /work/main/.venv-py/bin/python); the data is generated, never committed.
"""
import sys

import numpy as np

SCENE = """<?xml version="1.0" encoding="utf-8"?>
<!-- A displaced sphere of {tris} triangles (scripts/make_big_ply.py). -->
<scene version="3.0.0">
    <integrator type="path">
        <integer name="max_depth" value="4"/>
    </integrator>
    <sensor type="perspective">
        <float name="fov" value="35"/>
        <transform name="to_world">
            <lookat origin="0, 0.5, 4" target="0, 0, 0" up="0, 1, 0"/>
        </transform>
        <sampler type="independent">
            <integer name="sample_count" value="4"/>
        </sampler>
        <film type="hdrfilm">
            <integer name="width" value="256"/>
            <integer name="height" value="256"/>
            <rfilter type="box"/>
        </film>
    </sensor>
    <shape type="{kind}">
        <string name="filename" value="{mesh}"/>
        <bsdf type="diffuse">
            <rgb name="reflectance" value="0.7, 0.6, 0.5"/>
        </bsdf>
    </shape>
    <emitter type="directional">
        <vector name="direction" x="-0.5" y="-1" z="-0.6"/>
        <rgb name="irradiance" value="3, 2.8, 2.5"/>
    </emitter>
    <emitter type="constant">
        <rgb name="radiance" value="0.15, 0.2, 0.3"/>
    </emitter>
</scene>
"""


def sphere(n_tris):
    """A lat-long grid of about n_tris triangles (2 per cell), radius displaced."""
    n_lat = max(2, int(round((n_tris / 4) ** 0.5)))
    n_lon = max(3, n_tris // (2 * n_lat))
    theta = np.linspace(0.0, np.pi, n_lat + 1)[:, None]
    phi = np.linspace(0.0, 2.0 * np.pi, n_lon + 1)[None, :]
    r = 1.0 + 0.05 * np.sin(9.0 * theta) * np.sin(7.0 * phi) + 0.01 * np.sin(61.0 * phi)
    xyz = np.stack(
        [r * np.sin(theta) * np.cos(phi), r * np.cos(theta), r * np.sin(theta) * np.sin(phi)],
        axis=-1,
    ).astype("<f4").reshape(-1, 3)
    i = np.arange(n_lat)[:, None]
    j = np.arange(n_lon)[None, :]
    a = (i * (n_lon + 1) + j).ravel()
    b, c, d = a + 1, a + n_lon + 1, a + n_lon + 2
    faces = np.empty((2 * a.size, 3), dtype="<i4")
    faces[0::2] = np.stack([a, c, b], axis=-1)
    faces[1::2] = np.stack([b, c, d], axis=-1)
    return xyz, faces


def write_ply(path, xyz, faces):
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment scripts/make_big_ply.py\n"
        f"element vertex {len(xyz)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    rec = np.empty(len(faces), dtype=np.dtype([("n", "u1"), ("i", "<i4", (3,))], align=False))
    rec["n"] = 3
    rec["i"] = faces
    with open(path, "wb") as f:
        f.write(header.encode())
        f.write(xyz.tobytes())
        f.write(rec.tobytes())


def write_obj(path, xyz, faces):
    with open(path, "w") as f:
        np.savetxt(f, xyz, fmt="v %.9g %.9g %.9g")
        np.savetxt(f, faces + 1, fmt="f %d %d %d")


def main():
    n, stem = int(sys.argv[1]), sys.argv[2]
    xyz, faces = sphere(n)
    write_ply(stem + ".ply", xyz, faces)
    with open(stem + ".xml", "w") as f:
        f.write(SCENE.format(tris=len(faces), kind="ply", mesh=stem + ".ply"))
    if "--obj" in sys.argv[3:]:
        write_obj(stem + ".obj", xyz, faces)
        with open(stem + "_obj.xml", "w") as f:
            f.write(SCENE.format(tris=len(faces), kind="obj", mesh=stem + ".obj"))
    print(f"{stem}.ply: {len(xyz)} vertices, {len(faces)} triangles")


if __name__ == "__main__":
    main()
