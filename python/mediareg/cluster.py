"""Chunked renders on a Ray cluster (PyPI ``ray``; ``pip install ray``).

    import ray, mediareg.cluster
    ray.init()                      # or ray.init(address="auto") on a cluster
    r = mediareg.cluster.render("mitsuba_scenes/cbox.xml", spp=4096, chunks=64,
                                out="cbox.exr")
    r["image"], r["variance"]       # the merged mean and the variance of that mean

Each chunk is one Ray task: ``mediareg.render`` of spp/chunks samples with its own seed
(seed, seed + 1, ...), on whichever node Ray places it; the driver merges the chunks as
``mediareg merge`` does (weighted by their spp), so the result is the single render's in
distribution, with the variance of the mean from the chunks' spread. Every node must
see the scene and its meshes at the same path (a shared file system, or the same
checkout), and have this package installed.
"""

import os
import tempfile
import time

import mediareg


def split(spp, chunks):
    """Samples per chunk: spp split as evenly as integers allow (the first get one more)."""
    if chunks < 1 or spp < chunks:
        raise ValueError(f"spp={spp}, chunks={chunks}: need 1 <= chunks <= spp")
    return [spp // chunks + (k < spp % chunks) for k in range(chunks)]


def _render_chunk(scene_path, params, search_path, spp, seed, threads):
    scene = mediareg.load_file(scene_path, search_path=search_path, **params)
    return mediareg.render(scene, spp=spp, seed=seed, threads=threads), spp


def render(scene_path, spp, chunks, seed=0, out=None, search_path=None,
           threads_per_chunk=1, params=None):
    """Renders ``scene_path`` at ``spp`` samples per pixel as ``chunks`` Ray tasks of
    ``threads_per_chunk`` threads each (and as many CPUs reserved), seeds ``seed`` ..
    ``seed + chunks - 1``, and merges them. ``params``: the scene's parameters (as
    ``load_file``'s keywords). With ``out``, writes OUT.exr and OUT_var.exr (the
    variance of the mean) as ``mediareg merge`` does.

    Returns a dict: ``image``, ``variance`` (None for one chunk), ``spp``, ``chunks``,
    ``seeds`` and ``seconds`` (wall-clock time, rendering and merging).
    """
    import ray  # only here: the rest of mediareg does not need ray

    params = dict(params or {})
    scene_path = os.path.abspath(scene_path)
    search = None if search_path is None else [os.path.abspath(p) for p in search_path]
    # A bad scene fails here, on the driver, with the loader's message.
    mediareg.load_file(scene_path, search_path=search, **params)
    counts = split(spp, chunks)
    seeds = [seed + k for k in range(chunks)]
    task = ray.remote(num_cpus=threads_per_chunk)(_render_chunk)
    t0 = time.perf_counter()
    refs = [task.remote(scene_path, params, search, n, s, threads_per_chunk)
            for n, s in zip(counts, seeds)]
    results = ray.get(refs)
    # Merged through the files, exactly as `mediareg merge` merges them.
    with tempfile.TemporaryDirectory(prefix="mediareg-chunks-") as tmp:
        paths = []
        for k, (img, n) in enumerate(results):
            p = os.path.join(tmp, f"chunk{k}.exr")
            mediareg.write_exr(p, img, spp=n)
            paths.append(p)
        merged = mediareg.merge(paths, out=out)
    merged["seeds"] = seeds
    merged["seconds"] = time.perf_counter() - t0
    return merged
