"""Chunked renders: chunks with distinct seeds, merged (`mediareg.merge`, the CLI's merge;
`mediareg.cluster.render` on a local Ray cluster), agree statistically with a single
render of as many samples; the same comparison catches a 2% change of the walls'
reflectance (power)."""

import math
import os
import time

import numpy as np
import pytest

import mediareg
import mediareg.cluster
from conftest import require, scene

CHUNKS = 8
SPP = 16
# |z| beyond this: a false alarm with probability ~6e-5 per channel (normal tails).
Z_MAX = 4.0


def z_scores(merged, single, single_spp):
    """Per channel, z of the summed difference merged − single over all pixels (the box
    filter makes pixels independent; channels share paths, so each is tested alone).
    Var(merged − single) = σ²/N + σ²/N_s per pixel, σ²/N being the merge's variance of
    the mean (Eq. M3), so it is that variance times 1 + N/N_s."""
    d = merged["image"].astype(np.float64) - single.astype(np.float64)
    v = merged["variance"].astype(np.float64) * (1 + merged["spp"] / single_spp)
    return [d[..., c].sum() / math.sqrt(v[..., c].sum()) for c in range(3)]


def render_chunks(tmp_path, **params):
    s = mediareg.load_file(scene("cbox"), **params)
    paths = []
    for k in range(CHUNKS):
        p = tmp_path / f"chunk{k}.exr"
        mediareg.write_exr(p, mediareg.render(s, spp=SPP, seed=k), spp=SPP)
        paths.append(p)
    return paths


def single(spp, seed=100, **params):
    return mediareg.render(mediareg.load_file(scene("cbox"), **params), spp=spp, seed=seed)


def test_merged_chunks_match_a_single_render(cli, tmp_path):
    paths = render_chunks(tmp_path)
    merged = mediareg.merge(paths, out=tmp_path / "merged.exr")
    assert merged["spp"] == CHUNKS * SPP and merged["chunks"] == CHUNKS
    # The module's merge is the CLI's: the same files, bit for bit.
    r = cli("merge", tmp_path / "cli.exr", *paths)
    assert r.returncode == 0, r.stderr
    for a, b in [("merged.exr", "cli.exr"), ("merged_var.exr", "cli_var.exr")]:
        assert (tmp_path / a).read_bytes() == (tmp_path / b).read_bytes()
    # Its variance is the chunks' spread over K (equal spp).
    chunks = np.stack([mediareg.read_exr(p).astype(np.float64) for p in paths])
    expected = chunks.var(axis=0, ddof=1) / CHUNKS
    np.testing.assert_allclose(merged["variance"], expected, rtol=1e-4, atol=1e-12)

    z = z_scores(merged, single(CHUNKS * SPP), CHUNKS * SPP)
    print(f"merged vs single render: z = {np.round(z, 2)}")
    assert max(map(abs, z)) < Z_MAX, z
    # Power: against a single render with the walls' reflectance 2% off (0.75 → 0.765).
    z = z_scores(merged, single(CHUNKS * SPP, wall_reflectance=0.765), CHUNKS * SPP)
    print(f"merged vs single render, reflectance 2% off: z = {np.round(z, 2)}")
    assert max(map(abs, z)) > Z_MAX, z


def test_split():
    assert mediareg.cluster.split(10, 4) == [3, 3, 2, 2]
    assert sum(mediareg.cluster.split(4096, 7)) == 4096
    with pytest.raises(ValueError):
        mediareg.cluster.split(3, 4)


@pytest.fixture(scope="module")
def local_ray():
    ray = require("ray", "MEDIAREG_NO_RAY")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


def test_ray_cluster_render_matches_a_single_render(local_ray, tmp_path):
    spp = CHUNKS * SPP
    merged = mediareg.cluster.render(
        scene("cbox"), spp=spp, chunks=CHUNKS, seed=0, out=tmp_path / "ray.exr"
    )
    assert merged["seeds"] == list(range(CHUNKS)) and merged["spp"] == spp
    assert (tmp_path / "ray.exr").exists() and (tmp_path / "ray_var.exr").exists()
    # The chunks are the module's renders of those seeds: the merge of the same chunks
    # rendered here is the same image, bit for bit.
    local = mediareg.merge(render_chunks(tmp_path))
    assert np.array_equal(merged["image"], local["image"])
    t = time.perf_counter()
    one = single(spp)
    seconds_one = time.perf_counter() - t
    z = z_scores(merged, one, spp)
    print(
        f"Ray ({os.cpu_count()} cores, 2 workers, {CHUNKS} chunks): {merged['seconds']:.2f} s; "
        f"one process, one render: {seconds_one:.2f} s; z = {np.round(z, 2)}"
    )
    assert max(map(abs, z)) < Z_MAX, z
    with pytest.raises(mediareg.SceneError, match="no_such_param"):
        mediareg.cluster.render(scene("cbox"), spp=8, chunks=2, params={"no_such_param": 1})


def test_ray_mitsuba_reference_equals_the_script(local_ray, tmp_path):
    require("mitsuba", "MEDIAREG_NO_MITSUBA")
    import hashlib
    import json
    import subprocess
    import sys

    from conftest import ROOT

    args = dict(spp=8, chunks=2, params={"res": 16}, variant="scalar_rgb")
    r = mediareg.cluster.mitsuba_reference(
        scene("cbox"), out=tmp_path / "ray", script=ROOT / "scripts/mitsuba_reference.py", **args
    )
    p = subprocess.run(
        [sys.executable, "scripts/mitsuba_reference.py", str(scene("cbox")), "--spp", "8",
         "--chunks", "2", "-D", "res=16", "--variant", "scalar_rgb", "--out", str(tmp_path / "script")],
        cwd=ROOT, capture_output=True, text=True,
    )
    assert p.returncode == 0, p.stderr
    mean = mediareg.read_exr(tmp_path / "script" / "cbox.exr")
    var = mediareg.read_exr(tmp_path / "script" / "cbox_var.exr")
    # The same chunks (seeds 1000, 1001), pooled in float32 files here and in float64
    # by the script: equal to float32 rounding.
    np.testing.assert_allclose(r["image"], mean, rtol=1e-5, atol=1e-7)
    np.testing.assert_allclose(r["variance"], var, rtol=1e-3, atol=1e-9)
    a = json.loads((tmp_path / "ray" / "cbox.json").read_text())
    b = json.loads((tmp_path / "script" / "cbox.json").read_text())
    for key in ["spp", "chunks", "seeds", "sha256", "variant", "params", "width", "height"]:
        assert a[key] == b[key], key
    # Each records its own images' sha256 (the files differ: written by mediareg's merge
    # and by Mitsuba).
    for folder, meta in [("ray", a), ("script", b)]:
        assert sorted(meta["images_sha256"]) == ["cbox.exr", "cbox_var.exr"], folder
        for f, want in meta["images_sha256"].items():
            assert hashlib.sha256((tmp_path / folder / f).read_bytes()).hexdigest() == want, f


def test_ray_backward_over_views_is_the_sum_of_each_views_gradient(local_ray):
    # The tutorial's scene: 5 sensors; three views, one a repeat of sensor 0 with another
    # adjoint. One thread a view, so each view's gradient is deterministic and the
    # driver's sum in view order is the local loop's to the bit.
    path = scene("volume_opt/volume_opt")
    rng = np.random.default_rng(5)
    views = [(s, rng.uniform(0.0, 1.0, (64, 64, 3)).astype(np.float32)) for s in (0, 3, 0)]
    g = mediareg.cluster.backward(path, views, params=["sigma_t"], spp=2, seed=7)
    assert g["seeds"] == [7, 8, 9]
    want = None
    for (sensor, adjoint), s in zip(views, g["seeds"]):
        one = mediareg.backward(mediareg.load_file(path, sensor=sensor), adjoint,
                                params=["sigma_t"], spp=2, seed=s, threads=1)["sigma_t"]
        assert np.abs(one).max() > 0, "a view with no gradient tests nothing"
        want = one.copy() if want is None else want + one
    assert np.array_equal(g["sigma_t"], want)
    # Power: a view left out changes the sum.
    two = mediareg.cluster.backward(path, views[:2], params=["sigma_t"], spp=2, seed=7)
    assert not np.array_equal(two["sigma_t"], want)
    with pytest.raises(mediareg.SceneError):
        mediareg.cluster.backward(path, [(9, views[0][1])], spp=2)
