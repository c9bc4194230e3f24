"""The Python module against the command line: the same scene, spp and seed give the
same image bit for bit (and the same EXR file), the gradient likewise; bad input raises
the CLI's message and writes nothing; Ctrl-C stops a render."""

import os
import signal
import subprocess
import sys
import textwrap
import time

import numpy as np
import pytest

import mediareg
from conftest import ROOT, scene


def same_bits(a, b):
    return a.shape == b.shape and np.array_equal(a.view(np.uint32), b.view(np.uint32))


def test_render_equals_cli_bit_for_bit(cli, tmp_path):
    out = tmp_path / "cli.exr"
    r = cli("render", scene("cbox"), "--spp", 16, "--seed", 3, "--no-png", "-o", out)
    assert r.returncode == 0, r.stderr
    s = mediareg.load_file(scene("cbox"))
    img = mediareg.render(s, spp=16, seed=3)
    assert img.dtype == np.float32 and img.shape == (64, 64, 3)
    assert same_bits(img, mediareg.read_exr(out))
    # The same at another thread count, and written as the CLI writes it.
    assert same_bits(img, mediareg.render(s, spp=16, seed=3, threads=1))
    mediareg.write_exr(tmp_path / "py.exr", img, spp=16)
    assert (tmp_path / "py.exr").read_bytes() == out.read_bytes()
    # Another seed gives another image (the comparison can fail).
    assert not same_bits(img, mediareg.render(s, spp=16, seed=4))


def test_params_and_defaults_equal_cli(cli, tmp_path):
    out = tmp_path / "cli.exr"
    r = cli(
        "render", scene("cbox"), "-D", "res=24", "-D", "wall_reflectance=0.5",
        "--seed", 0, "--no-png", "-o", out,
    )
    assert r.returncode == 0, r.stderr
    s = mediareg.load_file(scene("cbox"), res=24, wall_reflectance=0.5)
    assert (s.width, s.height, s.spp) == (24, 24, 64)
    assert same_bits(mediareg.render(s), mediareg.read_exr(out))


def test_gradient_equals_cli_bit_for_bit(cli, tmp_path):
    out = tmp_path / "cube.exr"
    args = ["-D", "res=32", "--spp", 8, "--seed", 1, "--gradient", "albedo"]
    r = cli("render", scene("medium_cube"), *args, "--no-png", "-o", out)
    assert r.returncode == 0, r.stderr
    s = mediareg.load_file(scene("medium_cube"), res=32)
    img, grad = mediareg.render(s, spp=8, seed=1, gradient="albedo")
    assert same_bits(img, mediareg.read_exr(out))
    assert same_bits(grad, mediareg.read_exr(tmp_path / "cube_dalbedo.exr"))
    assert np.abs(grad).max() > 0
    # The radiance is the plain render's: the derivative rides the same paths.
    assert same_bits(img, mediareg.render(s, spp=8, seed=1))


def test_medium_derivatives_equal_cli_bit_for_bit(cli, tmp_path):
    out = tmp_path / "cube.exr"
    names = ["sigma_t", "albedo", "g", "scale"]
    args = ["-D", "res=16", "--spp", 8, "--seed", 2, "--gradient", ",".join(names)]
    r = cli("render", scene("medium_cube"), *args, "--no-png", "-o", out)
    assert r.returncode == 0, r.stderr
    s = mediareg.load_file(scene("medium_cube"), res=16)
    img, grads = mediareg.render(s, spp=8, seed=2, gradient=names)
    assert sorted(grads) == sorted(names)
    assert same_bits(img, mediareg.read_exr(out))
    for name in names:
        assert same_bits(grads[name], mediareg.read_exr(tmp_path / f"cube_d{name}.exr")), name
        assert np.isfinite(grads[name]).all() and np.abs(grads[name]).max() > 0, name
    # scale 1: d/dscale = sigma_t d/dsigma_t (sigma_t 10), in the same paths.
    np.testing.assert_allclose(grads["scale"], 10 * grads["sigma_t"], rtol=1e-5, atol=1e-6)
    # The radiance is the plain render's: sampling is detached, the draws the same.
    assert same_bits(img, mediareg.render(s, spp=8, seed=2))
    with pytest.raises(ValueError, match="list"):
        mediareg.render(s, spp=1, gradient="sigma_t,g")


def test_fit_moves_toward_the_target():
    target = mediareg.read_exr(ROOT / "tests/fixtures/fit/thin_cube_mitsuba.exr")
    r = mediareg.fit(scene("medium_cube"), [target], spp=8, iterations=30, res=64,
                     max_depth=64, sigma_t=1.2, albedo=0.6, g=0)
    assert sorted(r) == ["ci", "converged", "iterations", "loss", "params", "seconds"]
    assert sorted(r["params"]) == ["albedo", "g", "sigma_t"] and r["iterations"] == 30
    # Mitsuba rendered sigma_t 2.5, albedo 0.8, g 0.5; the start was 1.2, 0.6, 0.
    assert abs(r["params"]["sigma_t"] - 2.5) < 0.5 and abs(r["params"]["albedo"] - 0.8) < 0.1
    with pytest.raises(ValueError, match="density"):
        mediareg.fit(scene("medium_cube"), [target], params=["density"], res=64)


def cli_error(cli, *args):
    r = cli(*args)
    assert r.returncode != 0
    assert r.stderr.startswith("error: "), r.stderr
    return r.stderr[len("error: "):].rstrip("\n")


@pytest.mark.parametrize(
    "name, params",
    [
        ("tests/bad_input/cyclic_include_a.xml", {}),
        ("mitsuba_scenes/cbox.xml", {"no_such_param": 1}),
        ("mitsuba_scenes/cbox.xml", {"res": "wide"}),
    ],
)
def test_bad_scene_raises_the_cli_message(cli, tmp_path, name, params):
    path = ROOT / name
    defines = [a for k, v in params.items() for a in ("-D", f"{k}={v}")]
    out = tmp_path / "out.exr"
    expected = cli_error(cli, "render", path, *defines, "--no-png", "-o", out)
    with pytest.raises(mediareg.SceneError) as e:
        mediareg.load_file(path, **params)
    assert str(e.value) == expected
    # It starts with the file at fault (the included one for a cyclic include).
    assert str(e.value).startswith(str(path.parent)), str(e.value)
    assert ".xml" in str(e.value).split(": ")[0], str(e.value)
    assert list(tmp_path.iterdir()) == []


def test_bad_scene_message_names_file_line_col():
    with pytest.raises(mediareg.SceneError) as e:
        mediareg.load_file(scene("cbox"), res="wide")
    # file:line:col of the width's <integer>, as a compiler would print it.
    assert f"{scene('cbox')}:24:" in str(e.value), str(e.value)


def test_sensor_is_chosen_at_load():
    with pytest.raises(mediareg.SceneError, match="1 <sensor>"):
        mediareg.load_file(scene("cbox"), res=8, sensor=1)
    s = mediareg.load_file(scene("cbox"), res=8, sensor=0)
    assert mediareg.render(s, spp=1, sensor=0).shape == (8, 8, 3)


def test_bad_arguments_raise_and_write_nothing(tmp_path):
    s = mediareg.load_file(scene("cbox"), res=8)
    for kwargs, words in [
        ({"sensor": 1}, "sensor=1"),
        ({"spp": 0}, "spp"),
        ({"threads": 0}, "threads"),
        ({"gradient": "albedo"}, "volpath"),
        ({"gradient": "sigma_t"}, "sigma_t"),
    ]:
        with pytest.raises(ValueError, match=words):
            mediareg.render(s, **kwargs)
    cube = mediareg.load_file(scene("medium_cube"), res=8)
    with pytest.raises(ValueError, match="honey"):
        mediareg.render(cube, gradient="albedo", medium="honey")
    bad = np.full((4, 4, 3), 0.5, np.float32)
    bad[1, 2, 0] = np.nan
    with pytest.raises(mediareg.Error, match="NaN"):
        mediareg.write_exr(tmp_path / "nan.exr", bad)
    with pytest.raises(ValueError, match=r"\(H, W, 3\)"):
        mediareg.write_exr(tmp_path / "rgba.exr", np.zeros((4, 4, 4), np.float32))
    with pytest.raises(ValueError, match=".exr"):
        mediareg.write_exr(tmp_path / "image.png", np.zeros((4, 4, 3), np.float32))
    with pytest.raises(mediareg.Error, match="cannot"):
        mediareg.write_exr(tmp_path / "missing" / "a.exr", np.zeros((4, 4, 3), np.float32))
    with pytest.raises(mediareg.Error, match="spp"):
        mediareg.write_exr(tmp_path / "no_spp.exr", np.zeros((2, 2, 3), np.float32))
        mediareg.merge([tmp_path / "no_spp.exr"], out=tmp_path / "merged.exr")
    # Nothing but the one good file, no temporary left behind.
    assert sorted(p.name for p in tmp_path.iterdir()) == ["no_spp.exr"]


def test_ctrl_c_stops_a_render():
    code = textwrap.dedent(
        f"""
        import signal, sys, time, mediareg
        # A process started in the background by a non-interactive shell inherits SIGINT
        # ignored, and Python then raises no KeyboardInterrupt: restore its handler.
        signal.signal(signal.SIGINT, signal.default_int_handler)
        s = mediareg.load_file({str(scene('cbox'))!r})
        print("rendering", flush=True)
        try:
            mediareg.render(s, spp=1_000_000)
        except KeyboardInterrupt:
            print("interrupted", flush=True)
            sys.exit(0)
        sys.exit(1)
        """
    )
    p = subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.PIPE, text=True
    )
    assert p.stdout.readline().strip() == "rendering"
    time.sleep(1.0)
    t = time.monotonic()
    p.send_signal(signal.SIGINT)
    out, _ = p.communicate(timeout=60)
    assert p.returncode == 0 and "interrupted" in out, out
    # A million spp would take minutes; the render stopped at once.
    assert time.monotonic() - t < 10


@pytest.mark.parametrize(
    "flags, kwargs",
    [
        (["--factor", "0.8", "--denoise", "bilateral"], {"factor": 0.8, "denoise": "bilateral"}),
        (
            ["--predict", "paper", "--orbit", "1", "--no-spatial"],
            {"predict": "paper", "orbit": 1.0, "spatial": False},
        ),
    ],
)
def test_regularize_equals_cli_bit_for_bit(cli, tmp_path, flags, kwargs):
    out = tmp_path / "reg.exr"
    common = ["-D", "res=24", "--spp", 4, "--seed", 2, "--frames", 3]
    r = cli("regularize", scene("medium_cube"), *common, *flags, "--no-png", "-o", out)
    assert r.returncode == 0, r.stderr
    s = mediareg.load_file(scene("medium_cube"), res=24)
    got = mediareg.regularize(s, spp=4, seed=2, frames=3, **kwargs)
    for key, suffix in [
        ("predicted", ""),
        ("source", "_source"),
        ("dalbedo_raw", "_dalbedo_raw"),
        ("dalbedo", "_dalbedo"),
    ]:
        assert same_bits(got[key], mediareg.read_exr(tmp_path / f"reg{suffix}.exr")), key
    assert got["frames"] == 3
    if "factor" in kwargs:
        source, target = np.array(got["albedo_source"]), np.array(got["albedo_target"])
        np.testing.assert_allclose(source, kwargs["factor"] * target, rtol=1e-6)


def test_regularize_bad_arguments():
    cube = mediareg.load_file(scene("medium_cube"), res=8)
    for kwargs, words in [
        ({"predict": "cubic"}, "cubic"),
        ({"factor": "half"}, "half"),
        ({"c_beta": "big"}, "big"),
        ({"orbit": 1.0, "dolly": 0.1}, "exclude"),
        ({"target": (0, 0, 0)}, "orbit"),
        ({"medium": "honey"}, "honey"),
        ({"factor": 1.5}, "1.5"),
        ({"denoise": "blur"}, "blur"),
    ]:
        with pytest.raises(ValueError, match=words):
            mediareg.regularize(cube, spp=1, frames=1, **kwargs)
    with pytest.raises(ValueError, match="no medium"):
        mediareg.regularize(mediareg.load_file(scene("cbox"), res=8), spp=1, factor=0.9)


def test_denoise_equals_cli_bit_for_bit(cli, tmp_path):
    out = tmp_path / "cli.exr"
    r = cli("render", scene("cbox"), "--spp", 8, "--seed", 2, "--no-png", "--denoise", "oidn",
            "-o", out)
    assert r.returncode == 0, r.stderr
    s = mediareg.load_file(scene("cbox"))
    img = mediareg.render(s, spp=8, seed=2, denoise="oidn")
    noisy = mediareg.render(s, spp=8, seed=2)
    assert same_bits(noisy, mediareg.read_exr(tmp_path / "cli_noisy.exr"))
    # Bit for bit: OIDN's input scale is mediareg's, not its own parallel sum (which made
    # the two differ by up to 5e-5 relative).
    assert same_bits(img, mediareg.read_exr(out))
    assert not np.allclose(img, noisy, rtol=1e-3)


def test_denoise_arrays():
    s = mediareg.load_file(scene("cbox"))
    noisy = mediareg.render(s, spp=4, seed=1)
    a = mediareg.denoise(noisy)
    assert a.shape == noisy.shape and a.dtype == np.float32
    # Bit for bit, also after a call on another size: with OIDN's own input scale (a
    # parallel float sum) 1 call in 11 differed by up to 5e-5 relative.
    for _ in range(5):
        mediareg.denoise(noisy[:40, :50])
        assert same_bits(a, mediareg.denoise(noisy))
    # Nearer a converged render than its input, away from the light (whose edges the
    # colour-only filter blurs: render(denoise=) keeps it out).
    ref = mediareg.render(s, spp=1024, seed=9)
    dim = ref.max(axis=2) < 1.0
    err = lambda x: float(np.mean((x - ref)[dim] ** 2))
    assert err(a) < 0.5 * err(noisy)
    albedo = np.full_like(noisy, 0.5)
    assert mediareg.denoise(noisy, albedo=albedo).shape == noisy.shape
    bad = noisy.copy()
    bad[3, 4, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        mediareg.denoise(bad)
    with pytest.raises(ValueError, match="albedo"):
        mediareg.denoise(noisy, normal=albedo)
    with pytest.raises(ValueError, match="oidn"):
        mediareg.render(s, spp=1, denoise="bilateral")


OIDN_PROBE = textwrap.dedent("""
    import json, sys
    import numpy as np
    import mediareg
    root = sys.argv[1]
    cbox = mediareg.load_file(root + "/mitsuba_scenes/cbox.xml", res=8)
    cube = mediareg.load_file(root + "/mitsuba_scenes/medium_cube.xml", res=8)
    calls = {
        "denoise": lambda: mediareg.denoise(np.full((8, 8, 3), 0.5, np.float32)),
        "render": lambda: mediareg.render(cbox, spp=1, denoise="oidn"),
        "regularize": lambda: mediareg.regularize(cube, spp=1, frames=1, denoise="oidn"),
    }
    out = {}
    for name, call in calls.items():
        try:
            call()
            out[name] = None
        except Exception as e:
            out[name] = [type(e).__name__, str(e)]
    print(json.dumps(out))
""")


def oidn_calls(library):
    """denoise, render(denoise="oidn") and regularize(denoise="oidn") in a fresh process
    (the library is loaded once a process) with MEDIAREG_OIDN = `library` (None: unset):
    each call's exception as [type, message], or None where it returned."""
    env = dict(os.environ)
    env.pop("MEDIAREG_OIDN", None)
    if library is not None:
        env["MEDIAREG_OIDN"] = library
    r = subprocess.run([sys.executable, "-c", OIDN_PROBE, str(ROOT)], env=env,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr
    import json
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_a_missing_or_wrong_oidn_is_a_clear_error_in_python():
    # Nothing at the path: each call raises, saying so and how to get the library.
    for name, err in oidn_calls("/nonexistent/libOpenImageDenoise.so.1.4.3").items():
        assert err is not None, f"{name} returned without the library"
        assert "not found" in err[1] and "scripts/fetch_oidn" in err[1], (name, err)
    # A shared library that is not OIDN: mediareg's own native module, there on every
    # machine that runs these tests (a system library's path is not).
    not_oidn = mediareg._mediareg.__file__
    for name, err in oidn_calls(not_oidn).items():
        assert err is not None, f"{name} returned with {not_oidn} as OIDN"
        assert "no function oidnNewDevice" in err[1], (name, err)
    # The library found as scripts/fetch_oidn puts it: every call returns (so the
    # checks above see the missing library, not some other failure).
    assert oidn_calls(None) == {"denoise": None, "render": None, "regularize": None}


def _read_vol(path):
    b = open(path, "rb").read()
    nx, ny, nz, ch = np.frombuffer(b[8:24], dtype=np.int32)
    return np.frombuffer(b[48:], dtype=np.float32).reshape(nz, ny, nx)


def test_backward_equals_cli(cli, tmp_path):
    # The gradient sums per-thread buffers, so it is the CLI's to rounding, not bit
    # for bit; one thread each here, in the same order: equal to 1e-6 of its scale.
    path = ROOT / "mitsuba_scenes/grid_adjoint.xml"
    adjoint = mediareg.read_exr(ROOT / "mitsuba_scenes/grid_adjoint_A.exr")
    g = mediareg.backward(mediareg.load_file(path), adjoint, params=["sigma_t", "albedo"],
                          spp=8, seed=3, threads=1)
    assert sorted(g) == ["albedo", "sigma_t"] and g["sigma_t"].shape == (8, 8, 8)
    r = cli("backward", str(path), "--adjoint", str(ROOT / "mitsuba_scenes/grid_adjoint_A.exr"),
            "--params", "sigma_t,albedo", "--spp", "8", "--seed", "3", "-t", "1",
            "-o", str(tmp_path / "g"))
    assert r.returncode == 0, r.stderr
    for name in ["sigma_t", "albedo"]:
        want = _read_vol(tmp_path / f"g_{name}.vol")
        assert np.abs(g[name] - want).max() <= 1e-6 * np.abs(want).max(), name
    # A loop of one's own: the estimate written back with write_vol reloads the scene.
    mediareg.write_vol(tmp_path / "x.vol", np.full((8, 8, 8), 0.3, np.float32))
    s = mediareg.load_file(path, sigma_t_file=str(tmp_path / "x.vol"))
    assert mediareg.render(s, spp=1).shape == (24, 32, 3)
    with pytest.raises(ValueError, match="unknown volume"):
        mediareg.backward(s, adjoint, params=["g"])
