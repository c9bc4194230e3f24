"""Shared fixtures: the repository, the CLI binary (built by cargo if missing), the
optional packages the cluster tests need."""

import importlib
import os
import pathlib
import subprocess

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def scene(name):
    return ROOT / "mitsuba_scenes" / f"{name}.xml"


@pytest.fixture(scope="session")
def cli():
    """Runs `mediareg ARGS...` (target/release/mediareg, or $MEDIAREG_BIN)."""
    exe = os.environ.get("MEDIAREG_BIN")
    if exe is None:
        subprocess.run(
            ["cargo", "build", "--release", "--quiet", "--bin", "mediareg"],
            cwd=ROOT,
            check=True,
        )
        exe = ROOT / "target" / "release" / "mediareg"

    def run(*args):
        return subprocess.run(
            [str(exe), *map(str, args)], capture_output=True, text=True
        )

    return run


def require(module, opt_out):
    """Imports `module` for a test. scripts/test_python installs it, so its absence is a
    failure (a skip would pass a test that checked nothing) unless $`opt_out` is set,
    which scripts/test_python also reads to leave the package out."""
    if os.environ.get(opt_out):
        return pytest.importorskip(module, reason=f"{opt_out} is set")
    try:
        return importlib.import_module(module)
    except ImportError as e:
        pytest.fail(f"{module} is not installed ({e}): scripts/test_python installs it; "
                    f"set {opt_out}=1 to skip the tests that need it")
