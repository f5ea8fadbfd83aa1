"""Training data from Python: `sage3d.render_training_data` writes the files of
`sage3d data render`, `sage3d.training.TrainingSet` reads each of the three layouts back
(shapes, types, the preset's action words, one frame per action, NaVILA's frame histories,
poses at the episodes' starts, depth in metres), and `sage3d.distributed.render_training_data`
over Ray writes the single-machine render byte for byte."""

import json
import math
import os
import shutil

import numpy as np
import pytest

import sage3d as sg
from conftest import write_split
from sage3d.training import ACTIONS, TrainingSet

FORMATS = ("navila", "webdataset", "frames")
# Six episodes of two scenes (the `few` split of the `data` fixture), small frames: the debug
# build renders slowly. Walks that touch something are kept (the small homes are cramped).
RENDER = dict(split="few", limit=6, width=64, height=48, sensors="rgb,depth", keep_failed=True)
SHARD_SIZE = {"navila": 10, "webdataset": 2, "frames": None}


@pytest.fixture(scope="module")
def data(tmp_path_factory, sage3d):
    """Three synthetic homes and a dataset over them with a split `few` of six VLN episodes of
    the train split, three per scene of two scenes: two sharing a route (one walk for both)
    and one of another route. Returns (scenes, dataset)."""
    root = tmp_path_factory.mktemp("traindata")
    scenes = root / "scenes"
    for seed in (21, 22, 23):
        sage3d("scene", "synth", "--seed", seed, "--out", scenes / f"home{seed}", "--rooms", 3,
               "--objects", 25, "--gaussians", 2000)
    dataset = root / "dataset"
    sage3d("data", "build", scenes, "--out", dataset, "--per-scene", 3, "--seed", 7,
           "--balanced", 6, "--scene-unseen", 0, "--val", 0)
    routes = {}
    for line in (dataset / "episodes" / "train.jsonl").read_text().splitlines():
        ep = json.loads(line)
        if ep["task"] == "vln" and len(ep["reference_path"]) >= 2:
            key = json.dumps(ep["reference_path"])
            routes.setdefault(ep["scene"], {}).setdefault(key, []).append(line)
    few = []
    for by_path in list(routes.values())[:2]:
        first, second = list(by_path.values())[:2]
        few += first[:2] + second[:1]
    assert len(few) == 6, "expected two scenes in train with two routes each"
    write_split(dataset, "few", few)
    return scenes, dataset


@pytest.fixture(scope="module")
def renders(data, tmp_path_factory):
    """The training set of each format, rendered with the binding: {format: (out, manifest)}."""
    scenes, dataset = data
    root = tmp_path_factory.mktemp("renders")
    out = {}
    for fmt in FORMATS:
        manifest = sg.render_training_data(dataset, scenes, root / fmt, format=fmt,
                                           shard_size=SHARD_SIZE[fmt], **RENDER)
        out[fmt] = (root / fmt, manifest)
    return out


def tree(root):
    """Every file under `root` but the run record: {relative path: bytes}."""
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file() and p.name != "sage3d_run.json"}


def starts(dataset):
    eps = (json.loads(line) for line in (dataset / "episodes" / "train.jsonl").read_text().splitlines())
    return {e["episode_id"]: e["start"] for e in eps}


def test_binding_writes_the_command_lines_files(data, renders, sage3d, tmp_path):
    scenes, dataset = data
    out, manifest = renders["navila"]
    assert manifest == json.loads((out / "manifest.json").read_text())
    assert manifest["settings"]["format"] == "navila"
    assert manifest["counts"]["kept"] == 6 and manifest["counts"]["routes"] == 4
    assert manifest["counts"]["skipped"] == 0
    sage3d("data", "render", dataset, "--scenes", scenes, "--out", tmp_path / "cli", "--split", "few",
           "--limit", 6, "--width", 64, "--height", 48, "--sensors", "rgb,depth", "--keep-failed",
           "--shard-size", 10)
    assert tree(tmp_path / "cli") == tree(out)
    # A finished render is returned as it is.
    assert sg.render_training_data(dataset, scenes, out, format="navila", shard_size=10,
                                   **RENDER) == manifest


def test_settings_are_checked(data, tmp_path):
    scenes, dataset = data
    with pytest.raises(ValueError, match="unknown format"):
        sg.render_training_data(dataset, scenes, tmp_path / "a", format="tfrecord")
    with pytest.raises(ValueError, match="unknown action preset"):
        sg.render_training_data(dataset, scenes, tmp_path / "a", preset="habitat")
    with pytest.raises(ValueError, match="unknown sensor"):
        sg.render_training_data(dataset, scenes, tmp_path / "a", sensors=["rgb", "lidar"])
    # JSON has no NaN: the argument is named, not a parser's "expected value".
    with pytest.raises(ValueError, match="`hfov`: expected finite numbers, got nan"):
        sg.render_training_data(dataset, scenes, tmp_path / "a", hfov=float("nan"))
    with pytest.raises(ValueError, match="image"):
        sg.render_training_data(dataset, scenes, tmp_path / "a", image="webp")
    # Each bad value names its argument.
    with pytest.raises(ValueError, match="`jpeg_quality`: invalid value: integer `300`"):
        sg.render_training_data(dataset, scenes, tmp_path / "a", jpeg_quality=300)
    with pytest.raises(ValueError, match="`jpeg_quality` must be 1-100, got 0"):
        sg.render_training_data(dataset, scenes, tmp_path / "a", jpeg_quality=0)
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="notes.txt"):
        sg.render_training_data(dataset, scenes, tmp_path / "b", **RENDER)
    settings = json.loads(sg._sage3d.training_settings(dataset, scenes, sensors=["rgb", "depth"],
                                                        format="webdataset", step=0.4))
    assert settings["shard_size"] == 100 and settings["sensors"]["depth"]
    assert settings["preset"]["name"] == "custom" and settings["preset"]["step_m"] == pytest.approx(0.4)
    # NaVILA's wording is recorded with the preset; a step it cannot say in whole centimetres is
    # refused, naming the setting, before any work.
    navila = json.loads(sg._sage3d.training_settings(dataset, scenes, answers="navila"))
    assert navila["preset"]["answers"] == "navila"
    assert "answers" not in json.loads(sg._sage3d.training_settings(dataset, scenes))["preset"]
    with pytest.raises(ValueError, match="`answers` navila words the step in whole centimetres"):
        sg.render_training_data(dataset, scenes, tmp_path / "c", answers="navila", step=0.255)
    with pytest.raises(ValueError, match="unknown `answers` wording 'cm'"):
        sg.render_training_data(dataset, scenes, tmp_path / "c", answers="cm")
    # The motion cap has the command line's bounds (its `max_actions + 1` step limit never
    # overflows), for the one call and for the distributed steps' settings alike.
    for cap in (0, 1_000_001):
        with pytest.raises(ValueError, match="`max_actions`"):
            sg.render_training_data(dataset, scenes, tmp_path / "c", max_actions=cap)
        with pytest.raises(ValueError, match="`max_actions`"):
            sg._sage3d.training_settings(dataset, scenes, max_actions=cap)
    assert not (tmp_path / "c").exists()


def test_a_claim_holds_the_folder_against_the_command_line_until_released(data, sage3d, tmp_path):
    """The claim a distributed render's driver holds for the whole call: while it is held, a
    `sage3d data render` into the folder exits 1 naming this process, and no other claim or
    finish takes the folder."""
    scenes, dataset = data
    settings = sg._sage3d.training_settings(dataset, scenes, **RENDER)
    out = tmp_path / "held"
    with sg._sage3d.training_claim(settings, out) as claim:
        assert claim.held and claim.manifest is None and claim.out == out
        cli = sage3d("data", "render", dataset, "--scenes", scenes, "--out", out, "--split", "few",
                     "--limit", 6, check=False)
        assert cli.returncode == 1, cli.stderr
        assert f"being written by the `data render` run of process {os.getpid()}" in cli.stderr
        with pytest.raises(ValueError, match=f"process {os.getpid()}"):
            sg._sage3d.training_claim(settings, out)
        with pytest.raises(ValueError, match="being written"):
            sg._sage3d.training_finish(settings, out)
        with pytest.raises(ValueError, match="the claim holds"):
            sg._sage3d.training_finish(settings, tmp_path / "other", claim)
    assert not claim.held
    with pytest.raises(ValueError, match="was released"):
        sg._sage3d.training_finish(settings, out, claim)
    # Let go, the folder is claimed again at once (the same render: resumed).
    with sg._sage3d.training_claim(settings, out) as again:
        assert again.held and again.manifest is None


@pytest.mark.parametrize("fmt", FORMATS)
def test_episodes_of_each_format(data, renders, fmt):
    _, dataset = data
    out, manifest = renders[fmt]
    ts = TrainingSet(out)
    assert ts.format == fmt and ts.manifest == manifest
    assert len(ts) == manifest["counts"]["kept"] > 0
    start = starts(dataset)
    words = {"MOVE_FORWARD": "move forward 0.35 meter", "TURN_LEFT": "turn left 30 degree",
             "TURN_RIGHT": "turn right 30 degree", "STOP": "stop"}
    episodes = list(ts.episodes())
    assert len(episodes) == len(ts)
    frames = 0
    for ep in episodes:
        t = len(ep["actions"])
        assert t >= 2 and ep["actions"][-1] == "STOP" and set(ep["actions"]) <= set(ACTIONS)
        assert ep["words"] == [words[a] for a in ep["actions"]]
        assert ep["rgb"].dtype == np.uint8 and ep["rgb"].shape == (t, 48, 64, 3)
        assert ep["depth"].dtype == np.float32 and ep["depth"].shape == (t, 48, 64)
        hit = ep["depth"][ep["depth"] > 0]
        assert hit.size > 0 and hit.max() < 50
        assert ep["rgb"].std() > 0
        for key in ("poses", "commanded", "achieved"):
            assert ep[key].dtype == np.float32 and ep[key].shape == (t, 3)
        assert ep["contact"].shape == (t,)
        s = start[ep["episode_id"]]
        np.testing.assert_allclose(ep["poses"][0, :2], s["position"][:2], atol=1e-3)
        assert abs(math.remainder(float(ep["poses"][0, 2]) - s["yaw"], math.tau)) < 1e-3
        # Each frame's pose is where the action before it left the agent.
        np.testing.assert_allclose(ep["poses"][1:], ep["achieved"][:-1], atol=1e-6)
        assert ep["instruction"] and ep["verdict"] in ("clean", "collided", "far_from_goal")
        frames += t
    meta = list(ts.episodes(images=False))
    assert [e["episode_id"] for e in meta] == [e["episode_id"] for e in episodes]
    assert "rgb" not in meta[0]
    halves = [list(ts.episodes(images=False, shard=(i, 2))) for i in range(2)]
    assert sorted(e["episode_id"] for h in halves for e in h) == sorted(e["episode_id"] for e in meta)


def test_formats_hold_the_same_episodes(renders):
    by_format = {fmt: {e["episode_id"]: e for e in TrainingSet(renders[fmt][0]).episodes()}
                 for fmt in FORMATS}
    ref = by_format["frames"]
    for fmt in ("navila", "webdataset"):
        assert by_format[fmt].keys() == ref.keys()
        for eid, ep in by_format[fmt].items():
            assert ep["actions"] == ref[eid]["actions"] and ep["instruction"] == ref[eid]["instruction"]
            np.testing.assert_array_equal(ep["rgb"], ref[eid]["rgb"])
            np.testing.assert_array_equal(ep["depth"], ref[eid]["depth"])
            np.testing.assert_array_equal(ep["poses"], ref[eid]["poses"])


def test_webdataset_shards_and_navila_parts(renders):
    out, manifest = renders["webdataset"]
    shards = [f["path"] for f in manifest["files"]]
    assert len(shards) == math.ceil(manifest["counts"]["kept"] / 2) and not (out / "images").exists()
    out, manifest = renders["navila"]
    parts = sorted(out.glob("annotations_part_*.json"))
    assert len(parts) == math.ceil(manifest["counts"]["samples"] / 10)
    # The parts' samples, grouped by episode: step k has k + 1 frames, each list a prefix of
    # the episode's last.
    by_episode = {}
    for part in parts:
        for s in json.loads(part.read_text()):
            eid, step = s["video_id"].rsplit("-", 1)
            by_episode.setdefault(eid, {})[int(step)] = s
    assert sum(map(len, by_episode.values())) == manifest["counts"]["samples"]
    for samples in by_episode.values():
        last = samples[max(samples)]["frames"]
        assert sorted(samples) == list(range(len(last)))
        for k, s in samples.items():
            assert s["frames"] == last[:k + 1]
            assert s["a"].startswith("The next action is ") and s["a"].endswith(".")


@pytest.mark.parametrize("fmt", ["navila", "webdataset"])
def test_samples_are_frame_histories(renders, fmt):
    ts = TrainingSet(renders[fmt][0])
    episodes = {e["episode_id"]: e for e in ts.episodes()}
    count = 0
    for s in ts.samples():
        ep = episodes[s["episode_id"]]
        k = s["step"]
        assert s["video_id"] == f"{s['episode_id']}-{k}" and s["q"] == ep["instruction"]
        assert s["a"] == f"The next action is {ep['words'][k]}."
        assert s["frames"].dtype == np.uint8 and s["frames"].shape == (k + 1, 48, 64, 3)
        np.testing.assert_array_equal(s["frames"], ep["rgb"][:k + 1])
        assert s["depth"].shape == (k + 1, 48, 64)
        count += 1
    assert count == ts.manifest["counts"]["samples"]
    assert any(s["a"] == "The next action is move forward 0.35 meter." for s in ts.samples())


def test_unfinished_render_is_refused(tmp_path):
    with pytest.raises(FileNotFoundError, match="manifest.json"):
        TrainingSet(tmp_path)


def test_torch_dataset(renders):
    torch = pytest.importorskip("torch")
    from sage3d.training import TorchDataset

    ds = TorchDataset(renders["webdataset"][0])
    ts = TrainingSet(renders["webdataset"][0])
    items = list(torch.utils.data.DataLoader(ds, batch_size=None, num_workers=0))
    assert len(items) == len(ds) == len(ts)
    for item, ep in zip(items, ts.episodes()):
        t = len(ep["actions"])
        assert item["rgb"].dtype == torch.uint8 and tuple(item["rgb"].shape) == (t, 3, 48, 64)
        assert item["actions"].dtype == torch.int64
        assert item["actions"].tolist() == [ACTIONS.index(a) for a in ep["actions"]]
        assert tuple(item["depth"].shape) == (t, 48, 64)
    two = list(torch.utils.data.DataLoader(ds, batch_size=None, num_workers=2))
    assert sorted(i["episode_id"] for i in two) == sorted(i["episode_id"] for i in items)


@pytest.fixture(scope="module")
def local_ray():
    ray = pytest.importorskip("ray", reason="Ray is not installed for this Python")
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


@pytest.mark.parametrize("fmt", ["navila", "webdataset"])
def test_ray_render_equals_single_machine(local_ray, data, renders, tmp_path, fmt, capsys):
    from sage3d import distributed

    scenes, dataset = data
    out, manifest = renders[fmt]
    kwargs = dict(format=fmt, shard_size=SHARD_SIZE[fmt], **RENDER)
    got = distributed.render_training_data(dataset, scenes, tmp_path / "ray", **kwargs)
    assert got == manifest
    assert tree(tmp_path / "ray") == tree(out)
    scene_count = len(sg._sage3d.training_plan_scenes(
        sg._sage3d.training_settings(dataset, scenes, **kwargs)))
    assert scene_count >= 2
    assert capsys.readouterr().err.count(" walks, ") == scene_count
    if fmt == "navila":
        # Resume: a lost route and the finish are redone; the other scenes get no task.
        (tmp_path / "ray" / "manifest.json").unlink()
        route = sorted((tmp_path / "ray" / "images").glob("*/*/route.json"))[0].parent
        shutil.rmtree(route)
        again = distributed.render_training_data(dataset, scenes, tmp_path / "ray", **kwargs)
        assert again == manifest and tree(tmp_path / "ray") == tree(out)
        assert capsys.readouterr().err.count(" walks, ") == 1


def test_ray_task_failure_names_the_scene(local_ray, data, renders, tmp_path, monkeypatch):
    from sage3d import distributed

    scenes, dataset = data
    kwargs = dict(format="navila", shard_size=SHARD_SIZE["navila"], **RENDER)
    names = sg._sage3d.training_plan_scenes(sg._sage3d.training_settings(dataset, scenes, **kwargs))
    victim = names[-1]
    render_scene = distributed._render_training_scene

    def failing(settings_json, scene, done):  # shipped to the workers by value
        if scene == victim:
            raise OSError("disk full")
        return render_scene(settings_json, scene, done)

    monkeypatch.setattr(distributed, "_render_training_scene", failing)
    with pytest.raises(RuntimeError, match=f"scene {victim}: OSError: disk full"):
        distributed.render_training_data(dataset, scenes, tmp_path / "ray", progress=False, **kwargs)
    assert not (tmp_path / "ray" / "manifest.json").exists()
    written = {p.parts[-3] for p in (tmp_path / "ray" / "images").glob("*/*/route.json")}
    assert written == set(names) - {victim}
    # The rerun renders the missing scene only and gives the single-machine render.
    monkeypatch.setattr(distributed, "_render_training_scene", render_scene)
    manifest = distributed.render_training_data(dataset, scenes, tmp_path / "ray", progress=False,
                                                **kwargs)
    assert manifest == renders["navila"][1]
    assert tree(tmp_path / "ray") == tree(renders["navila"][0])
