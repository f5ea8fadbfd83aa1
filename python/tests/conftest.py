"""Shared fixtures: the sage3d binary under test and a small synthetic scene."""

import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
TESTDATA = REPO / "testdata" / "splats"


@pytest.fixture(scope="session")
def sage3d():
    """Runs the sage3d binary; returns the completed process (check=False)."""
    binary = os.environ.get("SAGE3D_BIN", str(REPO / "target" / "debug" / "sage3d"))
    assert pathlib.Path(binary).exists(), f"build sage3d first: {binary} is missing"

    def run(*args, check=True):
        proc = subprocess.run([binary, *map(str, args)], capture_output=True, text=True)
        if check and proc.returncode != 0:
            raise AssertionError(f"sage3d {' '.join(map(str, args))} failed:\n{proc.stderr}")
        return proc

    return run


@pytest.fixture(scope="session")
def small_scene(tmp_path_factory, sage3d):
    """A small synthetic home written by `sage3d scene synth`."""
    out = tmp_path_factory.mktemp("scene") / "home"
    sage3d("scene", "synth", "--seed", 3, "--out", out, "--rooms", 4, "--objects", 40, "--gaussians", 60000)
    return out
