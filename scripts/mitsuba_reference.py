#!/usr/bin/env python3
"""Render a reference image of a scene with the real Mitsuba 3 (pip package `mitsuba`).

Writes, into --out (default: reference/):
  NAME.exr        the mean of all chunks (linear RGB, float32)
  NAME_var.exr    per pixel and channel, the variance of that mean
                  (sample variance of the chunk images / number of chunks)
  NAME.json       provenance: Mitsuba version, variant, spp, chunks, seeds, seconds,
                  parameters, and the sha256 of the scene file, its includes and every
                  asset it names, so a test can tell when a reference has gone stale;
                  and the sha256 of NAME.exr and NAME_var.exr as written here
                  (images_sha256), so an image replaced afterwards is refused.

Each chunk renders spp/chunks samples per pixel with its own seed; chunks are
independent, so their spread estimates the variance of the mean.

With --extend, an existing reference NAME is made longer instead: --chunks more chunks of
its own spp per chunk, with the seeds after its last, are pooled with it (the pooled
mean and variance of all chunks, from the stored mean and variance: Chan et al.'s
parallel update of the sum of squared deviations). The merged files are written after
every chunk, so an interrupted run keeps what it rendered (run it again to go on).

A film with pixel_format luminance or luminance_alpha is stored with its Y in all three
channels; with --alpha, the film's alpha channel is (NAME_alpha).

With --crop X,Y,W,H only that window of the film is rendered (the JSON records it, and
the tests render the same window).

With --derivative NAME --step H (and -D NAME=VALUE), each chunk is instead the
derivative of the image with respect to the scene parameter NAME at VALUE, by
Richardson-extrapolated central differences (error O(H^4)):
  [8 (I(v + H/2) - I(v - H/2)) - (I(v + H) - I(v - H))] / (6 H),
the four renders sharing the chunk's seed (common random numbers: with Russian
roulette off, e.g. rr_depth >= max_depth, they follow the same paths). Output name
default: the scene's stem + "_d" + NAME.

Usage:
  scripts/mitsuba_reference.py mitsuba_scenes/cbox.xml --spp 4096 --chunks 8 \
      [-a ../shared/meshes] [-D name=value]... [--variant llvm_ad_rgb]
  scripts/mitsuba_reference.py mitsuba_scenes/lucy.xml --extend --chunks 16 -a .cache/meshes
"""
import argparse
import datetime
import hashlib
import json
import os
import re
import sys
import time
import xml.etree.ElementTree as ET


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def image_hashes(out):
    """images_sha256 of the reference at path prefix `out`: NAME.exr's and NAME_var.exr's
    sha256, keyed by file name (mediareg refuses images that no longer match)."""
    return {os.path.basename(f): sha256(f) for f in (out + ".exr", out + "_var.exr")}


def resolve(name, search):
    if os.path.isabs(name):
        return name if os.path.exists(name) else None
    for d in search:
        p = os.path.join(d, name)
        if os.path.exists(p):
            return p
    return None


def referenced_files(scene_path, search, params):
    """The scene file, its <include>s and every `filename` string property, resolved
    like Mitsuba's file resolver: the folders of <path value=...> tags first (the latest
    first; relative to the file they are in), then the scene folder, then each -a
    folder. Includes resolve as they are met; assets once every file is read, as Mitsuba
    instantiates plugins after parsing."""
    out = {}
    search = list(search)
    assets = []
    stack = [scene_path]
    while stack:
        path = stack.pop()
        out[os.path.basename(path)] = path
        root = ET.parse(path).getroot()
        for el in root.iter():
            def subst(v):
                return re.sub(r"\$([A-Za-z0-9_]+)", lambda m: params.get(m.group(1), m.group(0)), v)
            if el.tag == "default":
                params.setdefault(el.get("name"), el.get("value"))
            if el.tag == "path":
                value = subst(el.get("value"))
                here = os.path.join(os.path.dirname(path), value)
                d = here if os.path.isdir(here) else resolve(value, search)
                if d is None:
                    sys.exit(f"<path> {value} not found")
                search.insert(0, d)
            if el.tag == "include":
                p = resolve(subst(el.get("filename")), search)
                if p is None:
                    sys.exit(f"include {el.get('filename')} not found")
                stack.append(p)
            if el.tag == "string" and el.get("name") == "filename":
                assets.append(subst(el.get("value")))
    for name in assets:
        p = resolve(name, search)
        if p is None:
            sys.exit(f"asset {name} not found in {search}")
        out[os.path.basename(name)] = p
    return out


def set_variant(mi, variant=None):
    """Sets and returns `variant`, by default llvm_ad_rgb if it works (it needs LLVM >= 16,
    see README), else scalar_rgb."""
    if variant is None:
        variant = "scalar_rgb"
        if "llvm_ad_rgb" in mi.variants():
            try:
                mi.set_variant("llvm_ad_rgb")
                variant = "llvm_ad_rgb"
            except Exception:
                variant = "scalar_rgb"
    mi.set_variant(variant)
    return variant


def load_scenes(mi, scene, params, derivative=None, step=0.01, crop=None):
    """The (weight, scene) pairs whose weighted renders make one chunk: the scene, or
    with `derivative` the four of the finite-difference stencil (see the top). `crop`:
    [X, Y, W, H] of the film. Shared with mediareg.cluster.mitsuba_reference (Ray)."""
    if derivative is None:
        scenes = [(1.0, mi.load_file(scene, **params))]
    else:
        v, h = float(params[derivative]), step
        weights = [(dv, w / (6 * h)) for dv, w in [(h / 2, 8), (-h / 2, -8), (h, -1), (-h, 1)]]
        scenes = [(w, mi.load_file(scene, **{**params, derivative: repr(v + dv)}))
                  for dv, w in weights]
    if crop:
        for _, sc in scenes:
            # The film's crop window is a scene parameter in Mitsuba 3.
            p = mi.traverse(sc.sensors()[0])
            p["film.crop_offset"] = mi.ScalarPoint2u(crop[0], crop[1])
            p["film.crop_size"] = mi.ScalarVector2u(crop[2], crop[3])
            p.update()
    return scenes


def film_channels(img, alpha=False):
    """The film's colour as RGB (a luminance film's Y in all three channels), or with
    `alpha` its alpha channel (rgba, luminance_alpha) in all three."""
    import numpy as np
    c = img.shape[2]
    if alpha:
        if c not in (2, 4):
            sys.exit("--alpha: the film has no alpha channel (pixel_format rgba or luminance_alpha)")
        return np.repeat(img[:, :, c - 1:c], 3, axis=2)
    if c <= 2:
        return np.repeat(img[:, :, :1], 3, axis=2)
    return img[:, :, :3]


def render_chunk(mi, scenes, spp, seed, alpha=False):
    """One chunk: the weighted sum of the scenes' renders at `spp` with `seed`, float64 RGB
    (see film_channels)."""
    import numpy as np
    return sum(w * film_channels(np.array(mi.render(sc, spp=spp, seed=seed), dtype=np.float64),
                                 alpha)
               for w, sc in scenes)


def provenance(version, variant, scene, chunks, spp_chunk, seeds, seconds, shape, params,
               search, crop, hashes, derivative, step, images=None):
    """NAME.json's content (see the top). Shared with mediareg.cluster.mitsuba_reference.
    `images`: image_hashes() of the images just written."""
    return {
        "scene": os.path.relpath(os.path.abspath(scene)),
        "mitsuba_version": version,
        "variant": variant,
        "spp": chunks * spp_chunk,
        "chunks": chunks,
        "spp_per_chunk": spp_chunk,
        "seeds": seeds,
        "seconds": round(seconds, 3),
        "samples_per_second": round(shape[0] * shape[1] * chunks * spp_chunk / seconds, 1),
        "params": params,
        "search": search,
        "width": shape[1],
        "height": shape[0],
        **({"crop": crop} if crop else {}),
        "sha256": hashes,
        **({"images_sha256": images} if images else {}),
        "made_by": "scripts/mitsuba_reference.py",
        **({"derivative": {"param": derivative, "step": step,
                           "scheme": "Richardson central differences, common random numbers"}}
           if derivative else {}),
        "date": datetime.date.today().isoformat(),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("--spp", type=int, default=4096, help="total samples per pixel")
    ap.add_argument("--chunks", type=int, default=8, help="independent chunks (even, >= 2)")
    ap.add_argument("--seed", type=int, default=1000, help="seed of the first chunk")
    ap.add_argument("--variant", default=None, help="Mitsuba variant (default: llvm_ad_rgb if it works, else scalar_rgb)")
    ap.add_argument("-a", dest="search", action="append", default=[], help="extra search folder")
    ap.add_argument("-D", dest="defines", action="append", default=[], help="scene parameter name=value")
    ap.add_argument("--out", default="reference")
    ap.add_argument("--name", default=None, help="output name (default: the scene's stem)")
    ap.add_argument("--derivative", default=None, help="differentiate with respect to this -D parameter")
    ap.add_argument("--step", type=float, default=0.01, help="finite-difference step H for --derivative")
    ap.add_argument("--extend", action="store_true",
                    help="add --chunks chunks to the existing reference NAME (its spp per chunk, later seeds)")
    ap.add_argument("--alpha", action="store_true",
                    help="the film's alpha channel (pixel_format rgba or luminance_alpha) as the "
                         "image, in all three channels; output name: the scene's stem + _alpha")
    ap.add_argument("--crop", default=None, metavar="X,Y,W,H",
                    help="render only this window of the film (as mediareg render --crop)")
    args = ap.parse_args()
    if not args.extend and (args.chunks < 2 or args.spp % args.chunks):
        sys.exit("--chunks must be >= 2 and divide --spp")

    import mitsuba as mi
    import numpy as np

    variant = set_variant(mi, args.variant)

    params = dict(d.split("=", 1) for d in args.defines)
    scene_dir = os.path.dirname(os.path.abspath(args.scene))
    search = [scene_dir] + [os.path.abspath(a) for a in args.search]
    for d in args.search:
        mi.file_resolver().append(os.path.abspath(d))
    # Before rendering: a missing asset should not cost a render.
    files = referenced_files(os.path.abspath(args.scene), search, dict(params))
    if args.derivative is not None and args.derivative not in params:
        sys.exit(f"--derivative {args.derivative}: give its value with -D {args.derivative}=VALUE")
    crop = None
    if args.crop:
        crop = [int(v) for v in args.crop.split(",")]
        if len(crop) != 4:
            sys.exit("--crop needs X,Y,W,H")
    scenes = load_scenes(mi, args.scene, params, args.derivative, args.step, crop)

    name = args.name or os.path.splitext(os.path.basename(args.scene))[0]
    if args.derivative and not args.name:
        name += "_d" + args.derivative
    if args.alpha and not args.name:
        name += "_alpha"
    os.makedirs(args.out, exist_ok=True)
    out = os.path.join(args.out, name)
    hashes = {k: sha256(v) for k, v in sorted(files.items())}

    # Running pooled moments of the chunk images: n chunks, their mean, and m2, the sum of
    # squared deviations from it (variance of one chunk = m2 / (n - 1)).
    n, mean, m2, seeds, seconds_before = 0, None, None, [], 0.0
    spp_chunk = args.spp // args.chunks
    first_seed = args.seed
    if args.extend:
        with open(out + ".json") as f:
            old = json.load(f)
        if old["sha256"] != hashes or old["params"] != params or old.get("crop") != crop:
            sys.exit(f"--extend: {out}.json was made from other files, parameters or crop; "
                     "render it anew instead")
        if old["variant"] != variant or old["mitsuba_version"] != mi.__version__:
            sys.exit(f"--extend: {out}.json was made by Mitsuba {old['mitsuba_version']} "
                     f"{old['variant']}; extend it with the same (--variant)")
        n, spp_chunk, seeds = old["chunks"], old["spp_per_chunk"], list(old["seeds"])
        seconds_before = old["seconds"]
        mean = np.array(mi.Bitmap(out + ".exr"), dtype=np.float64)[:, :, :3]
        var_mean = np.array(mi.Bitmap(out + "_var.exr"), dtype=np.float64)[:, :, :3]
        m2 = var_mean * n * (n - 1)
        first_seed = max(seeds) + 1

    def write(suffix, arr):
        mi.Bitmap(arr.astype(np.float32), pixel_format=mi.Bitmap.PixelFormat.RGB).write(
            f"{out}{suffix}.exr.tmp.exr")
        os.replace(f"{out}{suffix}.exr.tmp.exr", f"{out}{suffix}.exr")

    t0 = time.time()
    for i in range(args.chunks):
        seed = first_seed + i
        img = render_chunk(mi, scenes, spp_chunk, seed, args.alpha)
        # Welford's update: exact pooling, one chunk at a time.
        n += 1
        if mean is None:
            mean, m2 = img.copy(), np.zeros_like(img)
        else:
            delta = img - mean
            mean += delta / n
            m2 += delta * (img - mean)
        seeds.append(seed)
        print(f"chunk {i + 1}/{args.chunks} done ({time.time() - t0:.1f} s)", flush=True)
        if n < 2:
            continue
        seconds = seconds_before + time.time() - t0
        write("", mean)
        write("_var", m2 / (n - 1) / n)
        meta = provenance(mi.__version__, variant, args.scene, n, spp_chunk, seeds, seconds,
                          mean.shape, params, args.search, crop, hashes, args.derivative,
                          args.step, images=image_hashes(out))
        with open(out + ".json.tmp", "w") as f:
            json.dump(meta, f, indent=2)
            f.write("\n")
        os.replace(out + ".json.tmp", out + ".json")
    print(f"wrote {out}.exr (+ _var, .json): {n} chunks, {n * spp_chunk} spp, with {variant}")

if __name__ == "__main__":
    main()
