"""`sage3d.distributed` on a local Ray instance: dataset generation with one task per scene gives
the dataset of `sage3d data build`, and evaluation with one task per scene gives the records and
summary of `sage3d eval`."""

import json

import pytest

import sage3d as sg

ray = pytest.importorskip("ray", reason="Ray is not installed for this Python")


@pytest.fixture(scope="module")
def local_ray():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def scenes(tmp_path_factory, sage3d):
    root = tmp_path_factory.mktemp("rayscenes")
    for seed in (11, 12, 13):
        sage3d("scene", "synth", "--seed", seed, "--out", root / f"home{seed}", "--rooms", 3,
               "--objects", 25, "--gaussians", 2000)
    return root


BUILD = ["--per-scene", 2, "--seed", 5, "--balanced", 6]


def test_generate_equals_data_build(local_ray, scenes, sage3d, tmp_path):
    from sage3d import distributed

    sage3d("data", "build", scenes, "--out", tmp_path / "cli", *BUILD)
    result = distributed.generate(scenes, tmp_path / "ray", per_scene=2, seed=5, balanced=6)
    assert [o["status"] for o in result["scenes"]] == ["done"] * 3
    cli_files = sorted(p.relative_to(tmp_path / "cli") for p in (tmp_path / "cli").rglob("*")
                       if p.is_file() and p.name != "sage3d_run.json")
    ray_files = sorted(p.relative_to(tmp_path / "ray") for p in (tmp_path / "ray").rglob("*")
                       if p.is_file() and p.name != "sage3d_run.json")
    assert ray_files == cli_files
    for rel in cli_files:
        assert (tmp_path / "ray" / rel).read_bytes() == (tmp_path / "cli" / rel).read_bytes(), rel
    run = lambda d: {k: v for k, v in json.loads((d / "sage3d_run.json").read_text()).items()}
    assert run(tmp_path / "ray")["config"] == run(tmp_path / "cli")["config"]
    again = distributed.generate(scenes, tmp_path / "ray", per_scene=2, seed=5, balanced=6)
    assert [o["status"] for o in again["scenes"]] == ["resumed"] * 3


class Forward:
    name = "forward"

    def act(self, obs):
        return 1


@pytest.mark.parametrize("agent", ["oracle", Forward()], ids=["builtin", "python"])
def test_evaluate_equals_cli_eval(local_ray, scenes, sage3d, tmp_path, agent):
    from sage3d import distributed

    data = tmp_path / "data"
    sage3d("data", "build", scenes, "--out", data, *BUILD)
    name = sg.evaluation.agent_name(agent)
    sage3d("eval", data, "--scenes", scenes, "--agent", name, "--split", "train", "--out", tmp_path / "cli")
    kwargs = {"sensors": []} if not isinstance(agent, str) else {}
    summary = distributed.evaluate(data, scenes, agent, tmp_path / "ray", split="train", **kwargs)
    assert (tmp_path / "ray" / "summary.json").read_bytes() == (tmp_path / "cli" / "summary.json").read_bytes()
    assert summary == json.loads((tmp_path / "cli" / "summary.json").read_text())
    lines = lambda d: (d / "episodes.jsonl").read_text().splitlines()
    ray_lines = lines(tmp_path / "ray")
    assert ray_lines == sorted(lines(tmp_path / "cli"), key=lambda l: json.loads(l)["episode_id"])
    assert [json.loads(l)["episode_id"] for l in ray_lines] == sorted(json.loads(l)["episode_id"] for l in ray_lines)
    shards = sorted(p.name for p in (tmp_path / "ray" / "shards").iterdir())
    assert shards == sorted({json.loads(l)["scene"] for l in ray_lines})
