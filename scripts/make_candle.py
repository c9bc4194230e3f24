#!/usr/bin/env python3
"""Writes the procedural candle of mitsuba_scenes/candle.xml (no public candle mesh
exists; the paper's is not published) into mitsuba_scenes/meshes/:

  candle_wax.ply    the wax body: a cylinder of radius 0.6 and height 2 standing on
                    y = 0, its top edge rounded (radius 0.12) and its top slightly
                    sunken towards the wick (0.04): a closed, watertight surface of
                    revolution with outward normals (the medium is inside)
  candle_wick.ply   the wick: a closed thin cylinder (radius 0.025), from just above
                    the wax to 0.22 above it
  candle_flame.ply  the flame: a closed teardrop of revolution above the wick, the
                    emitter

Binary little-endian PLY (float x y z, uchar/int faces), deterministic, no
dependencies: python3 scripts/make_candle.py"""
import math
import os
import struct

SEGMENTS = 96


def revolve(profile, segments=SEGMENTS):
    """A closed surface of revolution about +y. `profile` lists (r, y) from the bottom
    pole (r = 0) to the top pole (r = 0), going up the outside; faces wind
    counter-clockwise seen from outside, so normals point out."""
    assert profile[0][0] == 0 and profile[-1][0] == 0
    verts = [(0.0, profile[0][1], 0.0)]
    rings = profile[1:-1]
    for r, y in rings:
        for s in range(segments):
            phi = 2 * math.pi * s / segments
            verts.append((r * math.cos(phi), y, -r * math.sin(phi)))
    top = len(verts)
    verts.append((0.0, profile[-1][1], 0.0))

    def v(ring, s):
        return 1 + ring * segments + (s % segments)

    faces = []
    for s in range(segments):
        faces.append((0, v(0, s + 1), v(0, s)))
    for i in range(len(rings) - 1):
        for s in range(segments):
            a, b = v(i, s), v(i, s + 1)
            c, d = v(i + 1, s + 1), v(i + 1, s)
            faces.append((a, b, c))
            faces.append((a, c, d))
    last = len(rings) - 1
    for s in range(segments):
        faces.append((v(last, s), v(last, s + 1), top))
    return verts, faces


def signed_volume(verts, faces):
    vol = 0.0
    for a, b, c in faces:
        (ax, ay, az), (bx, by, bz), (cx, cy, cz) = verts[a], verts[b], verts[c]
        vol += (ax * (by * cz - bz * cy) - ay * (bx * cz - bz * cx) + az * (bx * cy - by * cx)) / 6
    return vol


def write_ply(path, verts, faces):
    assert signed_volume(verts, faces) > 0, f"{path}: normals must point outwards"
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        "comment mediareg scripts/make_candle.py\n"
        f"element vertex {len(verts)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n"
    )
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        for p in verts:
            f.write(struct.pack("<3f", *p))
        for t in faces:
            f.write(struct.pack("<B3i", 3, *t))


def wax(radius=0.6, height=2.0, round_r=0.12, dip=0.04):
    prof = [(0.0, 0.0), (radius, 0.0)]
    # The side, finely enough that flat shading does not show facets in the light.
    side_top = height - round_r
    for i in range(1, 8):
        prof.append((radius, side_top * i / 8))
    # The rounded edge: a quarter circle from the side to the top.
    for i in range(9):
        a = math.pi / 2 * i / 8
        prof.append((radius - round_r + round_r * math.cos(a), side_top + round_r * math.sin(a)))
    # The top sinks quadratically towards the wick.
    inner = radius - round_r
    for i in range(1, 6):
        r = inner * (1 - i / 6)
        prof.append((r, height - dip * (1 - (r / inner) ** 2)))
    prof.append((0.0, height - dip))
    return revolve(prof)


def wick(base, length=0.22, radius=0.025):
    prof = [(0.0, base), (radius, base), (radius, base + length * 0.5), (radius, base + length),
            (radius * 0.6, base + length + 0.01), (0.0, base + length + 0.015)]
    return revolve(prof, 24)


def flame(base, height=0.36, radius=0.075):
    """A teardrop: round at the bottom, pointed at the top."""
    prof = [(0.0, base)]
    n = 24
    for i in range(1, n):
        t = i / n
        # r(t) = sin(pi t) shaped towards the bottom, tapering to a point at the top.
        r = radius * math.sin(math.pi * t ** 0.7) * (1 - t) ** 0.3
        prof.append((max(r, 1e-4), base + height * t))
    prof.append((0.0, base + height))
    return revolve(prof, 48)


if __name__ == "__main__":
    out = os.path.join(os.path.dirname(__file__), "..", "mitsuba_scenes", "meshes")
    os.makedirs(out, exist_ok=True)
    wax_top = 2.0 - 0.04
    write_ply(os.path.join(out, "candle_wax.ply"), *wax())
    write_ply(os.path.join(out, "candle_wick.ply"), *wick(wax_top + 0.003))
    write_ply(os.path.join(out, "candle_flame.ply"), *flame(wax_top + 0.16))
