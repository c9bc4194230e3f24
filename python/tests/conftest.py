"""Shared fixtures: the repository, the CLI binary (built by cargo if missing)."""

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
