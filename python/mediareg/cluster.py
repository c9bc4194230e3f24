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

``backward`` does the same for reverse mode over many views: one task per view, the
per-view gradients summed on the driver (``mediareg.backward``'s arrays; a sum, so exact).
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


def _backward_view(scene_path, scene_params, search_path, sensor, adjoint, params, medium,
                   spp, seed, threads):
    scene = mediareg.load_file(scene_path, search_path=search_path, sensor=sensor,
                               **scene_params)
    return mediareg.backward(scene, adjoint, params=params, medium=medium, spp=spp,
                             seed=seed, threads=threads)


def backward(scene_path, views, params=None, medium=None, spp=None, seed=0,
             search_path=None, threads_per_view=1, scene_params=None):
    """The gradient of L = sum over views of sum(A_k * I_k) in a grid medium's values:
    ``views`` is a list of ``(sensor, adjoint)`` pairs (the sensor's index in the file,
    the adjoint image dL/dI for that view, (height, width, 3) float32), each one Ray task
    of ``mediareg.backward`` on the scene built for that sensor, view k at seed
    ``seed + k``. The driver sums the per-view gradients in view order: the merge is
    exact, the same sum a loop over ``mediareg.backward`` on one machine makes.

    Returns a dict: one float32 array per parameter (as ``mediareg.backward``),
    ``seeds`` and ``seconds`` (wall-clock time, the tasks and the sum).
    """
    import ray  # only here: the rest of mediareg does not need ray

    scene_params = dict(scene_params or {})
    scene_path = os.path.abspath(scene_path)
    search = None if search_path is None else [os.path.abspath(p) for p in search_path]
    if not views:
        raise ValueError("views: need at least one (sensor, adjoint) pair")
    # A bad scene or sensor fails here, on the driver, with the loader's message.
    for sensor in sorted({s for s, _ in views}):
        mediareg.load_file(scene_path, search_path=search, sensor=sensor, **scene_params)
    seeds = [seed + k for k in range(len(views))]
    task = ray.remote(num_cpus=threads_per_view)(_backward_view)
    t0 = time.perf_counter()
    refs = [task.remote(scene_path, scene_params, search, sensor, adjoint, params, medium,
                        spp, s, threads_per_view)
            for (sensor, adjoint), s in zip(views, seeds)]
    grads = ray.get(refs)
    total = {name: grads[0][name].copy() for name in grads[0]}
    for g in grads[1:]:
        for name in total:
            total[name] += g[name]
    total["seeds"] = seeds
    total["seconds"] = time.perf_counter() - t0
    return total


def _reference_script(script):
    """scripts/mitsuba_reference.py as a module (its chunk and provenance functions)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("mitsuba_reference", script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _mitsuba_chunk(script, scene_path, params, search, variant, derivative, step, crop,
                   spp, seed):
    import mitsuba as mi

    ref = _reference_script(script)
    variant = ref.set_variant(mi, variant)
    for d in search:
        mi.file_resolver().append(d)
    scenes = ref.load_scenes(mi, scene_path, params, derivative, step, crop)
    return ref.render_chunk(mi, scenes, spp, seed), mi.__version__, variant


def mitsuba_reference(scene_path, spp, chunks, seed=1000, out="reference", name=None,
                      params=None, search_path=None, variant=None, derivative=None,
                      step=0.01, crop=None, script="scripts/mitsuba_reference.py"):
    """A Mitsuba 3 reference as ``scripts/mitsuba_reference.py`` renders it (the same
    chunk function, seeds ``seed`` .. ``seed + chunks - 1``, spp/chunks each), the
    chunks as Ray tasks (one CPU each; every node needs the ``mitsuba`` package and the
    files at the same paths). Writes OUT/NAME.exr, NAME_var.exr (merged as ``mediareg
    merge`` does) and NAME.json (the script's provenance). Returns the merge's dict with
    ``seeds`` and ``seconds``."""
    import json

    import ray

    if chunks < 2 or spp % chunks:
        raise ValueError(f"chunks={chunks}: must be >= 2 and divide spp={spp}")
    script = os.path.abspath(script)
    if not os.path.exists(script):
        raise FileNotFoundError(f"{script}: pass script= (scripts/mitsuba_reference.py)")
    ref = _reference_script(script)
    params = {k: str(v) for k, v in (params or {}).items()}
    scene_path = os.path.abspath(scene_path)
    search = [os.path.abspath(p) for p in (search_path or [])]
    if derivative is not None and derivative not in params:
        raise ValueError(f"derivative={derivative}: give its value in params")
    # Before rendering: a missing asset should not cost a render.
    hashes = {k: ref.sha256(v) for k, v in sorted(ref.referenced_files(
        scene_path, [os.path.dirname(scene_path)] + search, dict(params)).items())}
    name = name or os.path.splitext(os.path.basename(scene_path))[0] + (
        "_d" + derivative if derivative else "")
    os.makedirs(out, exist_ok=True)
    task = ray.remote(num_cpus=1)(_mitsuba_chunk)
    seeds = [seed + k for k in range(chunks)]
    t0 = time.perf_counter()
    results = ray.get([task.remote(script, scene_path, params, search, variant, derivative,
                                   step, crop, spp // chunks, s) for s in seeds])
    with tempfile.TemporaryDirectory(prefix="mediareg-mitsuba-") as tmp:
        paths = []
        for k, (img, _, _) in enumerate(results):
            p = os.path.join(tmp, f"chunk{k}.exr")
            mediareg.write_exr(p, img, spp=spp // chunks)
            paths.append(p)
        merged = mediareg.merge(paths, out=os.path.join(out, name + ".exr"))
    seconds = time.perf_counter() - t0
    _, version, used_variant = results[0]
    images = ref.image_hashes(os.path.join(out, name))
    meta = ref.provenance(version, used_variant, scene_path, chunks, spp // chunks, seeds,
                          seconds, merged["image"].shape, params, search_path or [], crop,
                          hashes, derivative, step, images=images)
    meta["made_by"] = "mediareg.cluster.mitsuba_reference (scripts/mitsuba_reference.py's chunks on Ray)"
    with open(os.path.join(out, name + ".json.tmp"), "w") as f:
        json.dump(meta, f, indent=2)
        f.write("\n")
    os.replace(os.path.join(out, name + ".json.tmp"), os.path.join(out, name + ".json"))
    merged["seeds"] = seeds
    merged["seconds"] = seconds
    return merged
