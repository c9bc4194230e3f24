#!/usr/bin/env python3
"""Render a scene with the real Mitsuba 3 for `mediareg table`: a fixed spp, or as
many spp as fit in a time budget. Prints one JSON line on stdout:
  {"spp": N, "seconds": S, "variant": V, "mitsuba_version": X}
where S is the time of the render itself (scene loading and the warm-up render that
compiles Mitsuba's kernels are not counted, as mediareg's own timings count rendering).

With --budget, warm-up renders measure seconds per spp (at --calibrate-spp, then 4x
more until a render takes at least min(1 s, budget / 4); each size twice, the second
timed, so that JIT compilation is not counted), and the final spp is budget / (seconds
per spp). The final spp is rendered once untimed (compiling its kernels) and then timed. Large renders run in passes of at most 2^24 samples (each
its own seed) so the wavefront fits in memory; the image is their spp-weighted mean.

Usage:
  scripts/mitsuba_render.py SCENE.xml --out OUT.exr (--spp N | --budget SECONDS)
      [-a DIR]... [-D name=value]... [--seed S] [--variant V]
Exit status 3 when the mitsuba package cannot be imported."""
import argparse
import json
import os
import sys
import time


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("--out", required=True)
    g = ap.add_mutually_exclusive_group(required=True)
    g.add_argument("--spp", type=int)
    g.add_argument("--budget", type=float)
    ap.add_argument("--calibrate-spp", type=int, default=4)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--variant", default=None)
    ap.add_argument("-a", dest="search", action="append", default=[])
    ap.add_argument("-D", dest="defines", action="append", default=[])
    args = ap.parse_args()
    try:
        import mitsuba as mi
        import numpy as np
    except ImportError as e:
        print(f"mitsuba is not importable: {e}", file=sys.stderr)
        sys.exit(3)

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from mitsuba_reference import set_variant

    variant = set_variant(mi, args.variant)
    for d in args.search:
        mi.file_resolver().append(os.path.abspath(d))
    params = dict(d.split("=", 1) for d in args.defines)
    scene = mi.load_file(args.scene, **params)
    film = scene.sensors()[0].film()
    w, h = film.crop_size()
    pixels = w * h

    def render(spp, seed):
        """spp samples per pixel in passes of at most 2^24 samples; returns the mean."""
        per_pass = max(1, min(spp, (1 << 24) // pixels))
        acc, done, k = None, 0, 0
        while done < spp:
            n = min(per_pass, spp - done)
            img = np.array(mi.render(scene, spp=n, seed=seed + 7919 * k), dtype=np.float64)[:, :, :3]
            acc = img * n if acc is None else acc + img * n
            done += n
            k += 1
        return acc / spp

    spp = args.spp
    if spp is None:
        # Seconds per spp from a render long enough that launch overheads do not count:
        # each size is rendered twice and the second timed (the first compiles).
        c = args.calibrate_spp
        while True:
            render(c, args.seed + 1_000_000)
            t = time.time()
            render(c, args.seed + 2_000_000)
            elapsed = time.time() - t
            if elapsed >= min(1.0, args.budget / 4) or c >= 1 << 20:
                break
            c *= 4
        spp = max(1, int(args.budget * c / elapsed))
    # The kernels of this spp's passes compile here, outside the timed render.
    render(spp, args.seed + 3_000_000)
    t = time.time()
    img = render(spp, args.seed)
    seconds = time.time() - t
    mi.Bitmap(img.astype(np.float32), pixel_format=mi.Bitmap.PixelFormat.RGB).write(args.out)
    print(json.dumps({"spp": spp, "seconds": round(seconds, 3), "variant": variant,
                      "mitsuba_version": mi.__version__}))


if __name__ == "__main__":
    main()
