"""`sage3d data build` files read with Python's own gzip and json: the R2R-VLNCE layout and
Habitat-frame conventions (Y up, agents face -Z, quaternions [x, y, z, w]), the GVLN layout and
the JSONL episodes."""

import gzip
import json
import math

import numpy as np
import pytest


@pytest.fixture(scope="module")
def dataset(tmp_path_factory, sage3d):
    root = tmp_path_factory.mktemp("data")
    scenes = root / "scenes"
    for seed in (4, 5, 6):
        sage3d("scene", "synth", "--seed", seed, "--out", scenes / f"home{seed}", "--rooms", 4, "--objects", 40, "--gaussians", 1000)
    out = root / "dataset"
    sage3d("data", "build", scenes, "--out", out, "--per-scene", 5, "--seed", 2, "--balanced", 12)
    return out


def rotate(q, v):
    """Rotates v by the unit quaternion q = [x, y, z, w]."""
    x, y, z, w = q
    u = np.array([x, y, z])
    v = np.asarray(v, dtype=float)
    return 2 * np.dot(u, v) * u + (w * w - np.dot(u, u)) * v + 2 * w * np.cross(u, v)


def test_r2r_files_follow_vlnce_conventions(dataset):
    with gzip.open(dataset / "r2r" / "train" / "train.json.gz", "rt") as f:
        data = json.load(f)
    with gzip.open(dataset / "r2r" / "train" / "train_gt.json.gz", "rt") as f:
        gt = json.load(f)
    vocab = data["instruction_vocab"]["word_list"]
    assert vocab[:2] == ["<PAD>", "<UNK>"]
    episodes = data["episodes"]
    assert episodes
    for ep in episodes:
        assert isinstance(ep["episode_id"], int) and isinstance(ep["trajectory_id"], int)
        q = ep["start_rotation"]
        assert abs(np.linalg.norm(q) - 1) < 1e-5
        # Floor level: Y is up and the floor is y = 0.
        assert abs(ep["start_position"][1]) < 1e-6
        assert all(abs(p[1]) < 1e-6 for p in ep["reference_path"])
        assert len(ep["instruction"]["instruction_tokens"]) == 200
        words = [vocab[t] for t in ep["instruction"]["instruction_tokens"] if t != 0]
        assert " ".join(words) in ep["instruction"]["instruction_text"].lower().replace(",", "").replace(".", "")
        g = gt[str(ep["episode_id"])]
        assert g["actions"][-1] == 0 and set(g["actions"]) <= {0, 1, 2, 3}
        assert len(g["locations"]) == len(g["actions"]) + 1
        assert g["forward_steps"] == g["actions"].count(1)
        np.testing.assert_allclose(g["locations"][0], ep["start_position"], atol=1e-5)
        # The last location is within 0.2 m of the goal.
        assert np.linalg.norm(np.subtract(g["locations"][-1], ep["goals"][0]["position"])) < 0.2
        # The first forward step moves along the agent's -Z axis after the turns before it.
        actions = g["actions"]
        if 1 in actions:
            k = actions.index(1)
            turns = actions[:k].count(2) - actions[:k].count(3)
            yaw = math.radians(15 * turns)
            forward = rotate(q, [0, 0, -1])
            c, s = math.cos(yaw), math.sin(yaw)
            turned = np.array([c * forward[0] + s * forward[2], forward[1], -s * forward[0] + c * forward[2]])
            step = np.subtract(g["locations"][k + 1], g["locations"][k])
            np.testing.assert_allclose(step, 0.25 * turned, atol=1e-4)


def test_gvln_and_jsonl(dataset):
    gvln = json.loads((dataset / "gvln" / "train.json").read_text())
    assert gvln["dataset_metadata"]["name"] == "GVLN" and gvln["dataset_metadata"]["frame"] == "W"
    sample = gvln["scenes"][0]["samples"][0]
    point = sample["points"][0]
    assert len(point["position"]) == 3 and len(point["rotation"]) == 4
    assert {"instruction_type", "start", "end", "generated_instruction", "scene_id"} <= set(sample["instructions"][0])
    lines = (dataset / "episodes" / "train.jsonl").read_text().splitlines()
    episodes = [json.loads(line) for line in lines]
    assert all(5 <= len(e["instruction"].split()) <= 20 for e in episodes)
    summary = json.loads((dataset / "summary.json").read_text())
    total = sum(len((dataset / "episodes" / f"{s}.jsonl").read_text().splitlines()) for s in summary["by_split"])
    assert total == summary["episodes"]
