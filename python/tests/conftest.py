"""Shared fixtures: the sage3d binary under test and a small synthetic scene; the small
VLN split the model-server tests run on."""

import json
import os
import pathlib
import subprocess

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]
TESTDATA = REPO / "testdata" / "splats"

SMALL_SYNTH = {"seed": 2, "rooms": 3, "objects": 25, "gaussians": 20_000}
"""The synthetic home the environment tests make (`synth=`): small enough to render fast."""

SMALL_ENV = {"synth": SMALL_SYNTH, "width": 32, "height": 24, "num_episodes": 4, "seed": 1}
"""Environment settings of the environment tests: the small home, tiny frames, four episodes."""


def make_small_env(**kw):
    """`sage3d.make_env` with `SMALL_ENV`, `kw` overriding it."""
    import sage3d

    return sage3d.make_env(**{**SMALL_ENV, **kw})


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


@pytest.fixture(scope="module")
def synth_cache(tmp_path_factory):
    """Synthetic scenes made by the environments go to a fresh cache of this test session,
    shared by the modules that ask for it (`pytestmark = pytest.mark.usefixtures(...)`)."""
    mp = pytest.MonkeyPatch()
    mp.setenv("SAGE3D_CACHE", str(tmp_path_factory.getbasetemp() / "sage3d-cache"))
    yield
    mp.undo()


@pytest.fixture(scope="session")
def small_scene(tmp_path_factory, sage3d):
    """A small synthetic home written by `sage3d scene synth`."""
    out = tmp_path_factory.mktemp("scene") / "home"
    sage3d("scene", "synth", "--seed", 3, "--out", out, "--rooms", 4, "--objects", 40, "--gaussians", 60000)
    return out


def write_split(data, name, lines):
    """Writes the episode lines as split `name` of dataset `data` and lists it in its
    `splits.json`, as a split made by hand must be (a `*.jsonl` not listed is not a split)."""
    (data / "episodes" / f"{name}.jsonl").write_text("\n".join(lines) + "\n")
    listed = json.loads((data / "splits.json").read_text())
    listed["splits"][name] = [json.loads(line)["episode_id"] for line in lines]
    (data / "splits.json").write_text(json.dumps(listed, indent=2) + "\n")


def few_vln_split(sage3d, root):
    """A synthetic home under `root/scenes` and a dataset under `root/data` with a `few` split of
    three VLN episodes with distinct instructions (few rendered steps: the debug build renders
    slowly; distinct instructions let a server tell episodes apart). Returns (scenes, data,
    {episode_id: instruction})."""
    scenes = root / "scenes"
    sage3d("scene", "synth", "--seed", 1, "--out", scenes / "home1", "--rooms", 3, "--objects", 30, "--gaussians", 1000)
    data = root / "data"
    sage3d("data", "build", scenes, "--out", data, "--per-scene", 1, "--seed", 2)
    vln, seen = [], set()
    for line in (data / "episodes" / "train.jsonl").read_text().splitlines():
        ep = json.loads(line)
        if ep["task"] == "vln" and ep["instruction"] not in seen:
            seen.add(ep["instruction"])
            vln.append(line)
    vln = vln[:3]
    assert len(vln) == 3, "expected the built dataset to hold 3 VLN episodes with distinct instructions"
    write_split(data, "few", vln)
    return scenes, data, {json.loads(line)["episode_id"]: json.loads(line)["instruction"] for line in vln}
