"""`sage3d.distributed` on a local Ray instance: dataset generation with one task per scene gives
the dataset of `sage3d data build`, and evaluation with one task per scene gives the records and
summary of `sage3d eval`."""

import json
import os
import pathlib

import pytest

import sage3d as sg

ray = pytest.importorskip("ray", reason="Ray is not installed for this Python")


@pytest.fixture(scope="module")
def local_ray():
    # The workers import the agent class of this module by name, as a cluster imports a user's.
    here = str(pathlib.Path(__file__).parent)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             runtime_env={"env_vars": {"PYTHONPATH": here}})
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def scenes(tmp_path_factory, sage3d):
    root = tmp_path_factory.mktemp("rayscenes")
    for seed in (11, 12, 13):
        sage3d("scene", "synth", "--seed", seed, "--out", root / f"home{seed}", "--rooms", 3,
               "--objects", 25, "--gaussians", 2000)
    return root


@pytest.fixture(scope="module")
def cli_data(scenes, sage3d, tmp_path_factory):
    out = tmp_path_factory.mktemp("raydata") / "cli"
    sage3d("data", "build", scenes, "--out", out, "--per-scene", 2, "--seed", 5, "--balanced", 6)
    return out


def files(root):
    return sorted(p.relative_to(root) for p in root.rglob("*") if p.is_file() and p.name != "sage3d_run.json")


def test_generate_equals_data_build(local_ray, scenes, cli_data, tmp_path):
    from sage3d import distributed

    result = distributed.generate(scenes, tmp_path / "ray", per_scene=2, seed=5, balanced=6)
    assert [o["status"] for o in result["scenes"]] == ["done"] * 3
    assert files(tmp_path / "ray") == files(cli_data)
    for rel in files(cli_data):
        assert (tmp_path / "ray" / rel).read_bytes() == (cli_data / rel).read_bytes(), rel
    run = lambda d: json.loads((d / "sage3d_run.json").read_text())  # noqa: E731
    for key in ("config", "inputs", "status"):
        assert run(tmp_path / "ray")[key] == run(cli_data)[key], key
    assert run(tmp_path / "ray")["scenes"]["absolute"] == run(cli_data)["scenes"]["absolute"]
    again = distributed.generate(scenes, tmp_path / "ray", per_scene=2, seed=5, balanced=6)
    assert [o["status"] for o in again["scenes"]] == ["resumed"] * 3
    # A misspelt setting is named before any task starts, as build_dataset names it.
    with pytest.raises(ValueError, match="per_scen"):
        distributed.generate(scenes, tmp_path / "typo", per_scen=2)
    assert not (tmp_path / "typo").exists()


def test_the_driver_claim_holds_the_dataset_folder_until_released(scenes, sage3d, tmp_path):
    """The claim `generate`'s driver holds from before the tasks to the end of the assembly:
    meanwhile `sage3d data build` into the folder exits 1 naming this process, the scene steps
    (which take no lock) still write there, and the assembly takes only a held claim of its own
    folder."""
    settings = dict(per_scene=2, seed=5, balanced=6)
    out = tmp_path / "held"
    dirs = sg._sage3d.scene_dirs(scenes)
    with sg._sage3d.dataset_claim(out, **settings) as claim:
        assert claim.held and claim.manifest is None and claim.out == out
        cli = sage3d("data", "build", scenes, "--out", out, "--per-scene", 2, "--seed", 5, check=False)
        assert cli.returncode == 1, cli.stderr
        assert f"being written by the `data build` run of process {os.getpid()}" in cli.stderr
        with pytest.raises(ValueError, match=f"process {os.getpid()}"):
            sg._sage3d.dataset_claim(out, **settings)
        for d in dirs:
            outcome, _, _ = sg._sage3d.build_scene(d, out, **settings)
            assert outcome["status"] == "done"
        with pytest.raises(ValueError, match="being written"):
            sg._sage3d.assemble_dataset(out, dirs, scenes, **settings)
        with pytest.raises(ValueError, match="the claim holds"):
            sg._sage3d.assemble_dataset(tmp_path / "other", dirs, scenes, claim=claim, **settings)
        summary = sg._sage3d.assemble_dataset(out, dirs, scenes, claim=claim, **settings)
    assert not claim.held and summary["episodes"] > 0
    assert {"train", "val", "test_balanced"} <= set(sg._sage3d.list_splits(out))
    with pytest.raises(ValueError, match="was released"):
        sg._sage3d.assemble_dataset(out, dirs, scenes, claim=claim, **settings)


class Forward:
    name = "forward"

    def act(self, obs):
        return 1


@pytest.mark.parametrize("agent", ["oracle", Forward()], ids=["builtin", "python"])
def test_evaluate_equals_cli_eval(local_ray, scenes, cli_data, sage3d, tmp_path, agent, capfd):
    from sage3d import distributed

    name = sg.evaluation.agent_name(agent)
    sage3d("eval", cli_data, "--scenes", scenes, "--agent", name, "--split", "test_balanced",
           "--out", tmp_path / "cli")
    kwargs = {"sensors": []} if not isinstance(agent, str) else {}
    # No scenes: the folder the dataset records.
    summary = distributed.evaluate(cli_data, agent=agent, out=tmp_path / "ray", split="test_balanced", **kwargs)
    # The same files byte for byte: records sorted by episode id in both, no timings in either.
    for f in ("episodes.jsonl", "summary.json"):
        assert (tmp_path / "ray" / f).read_bytes() == (tmp_path / "cli" / f).read_bytes(), f
    assert summary == json.loads((tmp_path / "cli" / "summary.json").read_text())
    ray_lines = (tmp_path / "ray" / "episodes.jsonl").read_text().splitlines()
    by_id = lambda line: json.loads(line)["episode_id"]  # noqa: E731
    assert [by_id(line) for line in ray_lines] == sorted(map(by_id, ray_lines))
    shards = sorted(p.name for p in (tmp_path / "ray" / "shards").iterdir())
    assert shards == sorted({json.loads(line)["scene"] for line in ray_lines})
    # The merged run has its report, as `sage3d eval` writes one; the shards have none.
    assert (tmp_path / "ray" / "report.html").is_file()
    assert not any((tmp_path / "ray" / "shards" / n / "report.html").exists() for n in shards)
    # Progress on stderr (a line per task, or a tqdm bar), in episodes of the split.
    err = capfd.readouterr().err
    assert f"{len(ray_lines)}/{len(ray_lines)}" in err, err


class Crash:
    """An agent whose worker process dies on its first step, as on a node that is lost."""

    name = "crash"

    def act(self, obs):
        import os

        os._exit(1)


def test_a_task_whose_worker_dies_is_named_and_nothing_is_merged(local_ray, cli_data, tmp_path, capfd):
    from sage3d import distributed

    with pytest.raises(RuntimeError, match=r"scene tasks failed .*its worker process died \(WorkerCrashedError\)"):
        distributed.evaluate(cli_data, agent=Crash(), out=tmp_path / "ray", split="test_balanced", sensors=[],
                             max_retries=0)
    err = capfd.readouterr().err
    assert "task failed: its worker process died" in err, err
    assert not (tmp_path / "ray" / "summary.json").exists()
