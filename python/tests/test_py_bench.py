"""Datasets and the evaluator from Python against the CLI: the dataset API reads what
`sage3d data build` wrote, an environment runs its episodes, and `sage3d.evaluate` gives the
records and summary of `sage3d eval` — with the built-in agents and with a Python agent, on the
CPU or the GPU."""

import json
import os
import re
import signal
import threading

import numpy as np
import pytest

import sage3d as sg


@pytest.fixture(scope="module")
def data(tmp_path_factory, sage3d):
    root = tmp_path_factory.mktemp("pydata")
    scenes = root / "scenes"
    for seed in (7, 8):
        sage3d("scene", "synth", "--seed", seed, "--out", scenes / f"home{seed}", "--rooms", 3,
               "--objects", 25, "--gaussians", 2000)
    out = root / "dataset"
    sage3d("data", "build", scenes, "--out", out, "--per-scene", 2, "--seed", 3, "--balanced", 6)
    return scenes, out


def jsonl(path):
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def test_dataset_splits_episodes_and_slice_filters(data):
    _, out = data
    ds = sg.load_dataset(out)
    assert ds.splits == sorted(p.stem for p in (out / "episodes").glob("*.jsonl"))
    for split, episodes in ds:
        assert episodes == jsonl(out / "episodes" / f"{split}.jsonl")
    train = ds.episodes("train")
    vln_low = ds.episodes("train", task="vln", level="low")
    assert vln_low == [e for e in train if e["task"] == "vln" and e.get("level") == "low"]
    short_or_medium = ds.episodes("train", path=["short", "medium"])
    assert short_or_medium == [e for e in train if e["slices"]["path"] in ("short", "medium")]
    assert ds.episodes("train", level=None) == [e for e in train if "level" not in e]
    assert ds.summary() == json.loads((out / "summary.json").read_text())
    with pytest.raises(ValueError, match="unknown split 'nope'"):
        ds.episodes("nope")
    with pytest.raises(ValueError, match="unknown episode filter"):
        ds.episodes("train", colour="red")


def test_filter_episodes_takes_hand_made_dicts_without_slices():
    episodes = [{"id": "a", "task": "vln"},
                {"id": "b", "task": "vln", "slices": {"assets": "many", "path": "long"}}]
    assert [e["id"] for e in sg.filter_episodes(episodes, assets="many")] == ["b"]
    assert [e["id"] for e in sg.filter_episodes(episodes, path=None)] == ["a"]
    assert [e["id"] for e in sg.filter_episodes(episodes, task="vln")] == ["a", "b"]
    with pytest.raises(TypeError, match="episode 'c': slices: expected a dict"):
        sg.filter_episodes([{"id": "c", "slices": 3}], assets="many")


def test_env_over_a_dataset_starts_where_the_episodes_start(data):
    scenes, out = data
    env = sg.make_env(dataset=out, scenes=scenes, split="train", task="vln", width=16, height=16)
    for e in env.episodes[:3]:
        obs, info = env.reset(options={"episode_id": e["episode_id"]})
        assert obs["instruction"] == e["instruction"] and info["scene"] == e["scene"]
        np.testing.assert_allclose(obs["pose"], [*e["start"]["position"], e["start"]["yaw"]], atol=1e-5)
    with pytest.raises(ValueError, match="needs scenes="):
        sg.make_env(dataset=out)


def cli_eval(sage3d, data, agent, out, split="train", *flags):
    scenes, dataset = data
    sage3d("eval", dataset, "--scenes", scenes, "--agent", agent, "--split", split, "--out", out,
           *flags)
    return sorted(jsonl(out / "episodes.jsonl"), key=lambda r: r["episode_id"])


def test_metric_mode_and_dtw_from_python_equal_the_cli(data, sage3d, tmp_path):
    scenes, dataset = data
    expected = cli_eval(sage3d, data, "forward", tmp_path / "cli", "train", "--mode", "vlnce",
                        "--dtw", "fast")
    sg.evaluate(dataset, scenes, "forward", tmp_path / "py", split="train", mode="vlnce", dtw="fast")
    got = sorted(jsonl(tmp_path / "py" / "episodes.jsonl"), key=lambda r: r["episode_id"])
    assert got == expected
    summary = json.loads((tmp_path / "py" / "summary.json").read_text())
    assert summary["mode"] == "vlnce" and summary["dtw"] == "fast"
    assert (tmp_path / "py" / "summary.json").read_bytes() == (tmp_path / "cli" / "summary.json").read_bytes()
    # A run folder resumes only the same scoring.
    with pytest.raises(ValueError, match="other settings"):
        sg.evaluate(dataset, scenes, "forward", tmp_path / "py", split="train", mode="vlnce")
    with pytest.raises(ValueError, match="expected exact or fast"):
        sg.evaluate(dataset, scenes, "forward", tmp_path / "bad", split="train", dtw="approx")
    with pytest.raises(ValueError, match="scenes_only: 'nosuch' has no episode in split 'train'"):
        sg.evaluate(dataset, scenes, "forward", tmp_path / "bad", split="train", scenes_only=["nosuch"])
    with pytest.raises(ValueError, match="scenes_only: names no scene"):
        sg.evaluate(dataset, scenes, "forward", tmp_path / "bad", split="train", scenes_only=[])
    assert not (tmp_path / "bad").exists()
    # A folder of the user's files is written beside only with force, as `sage3d eval --force`.
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match="did not write"):
        sg.evaluate(dataset, scenes, "forward", mine, split="train", sensors=[])
    sg.evaluate(dataset, scenes, "forward", mine, split="train", sensors=[], force=True)
    assert (mine / "notes.txt").read_text() == "mine" and (mine / "summary.json").is_file()
    with pytest.raises(ValueError, match="`seed`: invalid value: integer `-1`"):
        sg.evaluate(dataset, scenes, "forward", tmp_path / "bad", split="train", seed=-1)


def test_the_bodies_choice_from_python_equals_the_cli(data, sage3d, tmp_path):
    scenes, dataset = data
    expected = cli_eval(sage3d, data, "forward", tmp_path / "cli", "train", "--splat-bodies", "always")
    sg.evaluate(dataset, scenes, "forward", tmp_path / "py", split="train", splat_bodies="always")
    got = sorted(jsonl(tmp_path / "py" / "episodes.jsonl"), key=lambda r: r["episode_id"])
    assert got == expected
    # The scenes' objects have meshes: only "always" gives them bodies from their Gaussians.
    assert all(r["bodies"].get("gaussians", 0) > 0 for r in got)
    record = json.loads((tmp_path / "py" / "sage3d_run.json").read_text())
    assert record["settings"]["splat_bodies"] == "always"
    with pytest.raises(ValueError, match="splat_bodies: always recorded, auto asked"):
        sg.evaluate(dataset, scenes, "forward", tmp_path / "py", split="train")
    with pytest.raises(ValueError, match="evaluate's own option"):
        sg.evaluate(dataset, scenes, "forward", tmp_path / "bad", split="train",
                    config={"splat_bodies": "never"})


def test_builtin_agents_from_python_equal_the_cli(data, sage3d, tmp_path):
    scenes, dataset = data
    expected = cli_eval(sage3d, data, "oracle", tmp_path / "cli")
    result = sg.evaluate(dataset, scenes, "oracle", tmp_path / "py", split="train")
    got = sorted(jsonl(tmp_path / "py" / "episodes.jsonl"), key=lambda r: r["episode_id"])
    assert got == expected
    assert (tmp_path / "py" / "summary.json").read_bytes() == (tmp_path / "cli" / "summary.json").read_bytes()
    assert result["summary"] == json.loads((tmp_path / "cli" / "summary.json").read_text())
    assert result["ran"] == result["total"] == len(expected) and "agent oracle" in result["table"]
    assert result["scene_changes"] == []
    # The report too, with a map per episode as `sage3d eval` draws them.
    assert (tmp_path / "py" / "report.html").is_file()
    maps = lambda run: sorted(p.name for p in (run / "report" / "maps").iterdir())  # noqa: E731
    assert maps(tmp_path / "py") == maps(tmp_path / "cli")
    again = sg.evaluate(dataset, scenes, "oracle", tmp_path / "py", split="train")
    assert again["resumed"] == len(expected) and again["ran"] == 0
    # Both record the environment they ran in, the same one.
    env = lambda run: json.loads((run / "sage3d_run.json").read_text())["env"]  # noqa: E731
    assert env(tmp_path / "py") == env(tmp_path / "cli") and env(tmp_path / "cli")["task"]["max_steps"] == 500


def test_scene_files_changed_since_the_dataset_was_built_are_named_with_a_warning(data, tmp_path):
    import shutil

    scenes, dataset = data
    moved = tmp_path / "scenes"
    shutil.copytree(scenes, moved)
    structure = moved / "home7" / "structure.json"
    structure.write_text(structure.read_text() + "\n")
    with pytest.warns(RuntimeWarning, match=re.escape("home7/structure.json changed")):
        result = sg.evaluate(dataset, moved, "forward", tmp_path / "run", split="train", sensors=[])
    assert result["scene_changes"] == ["home7/structure.json changed"]


def test_a_run_folder_resumes_only_the_environment_it_ran_in(data, tmp_path):
    scenes, dataset = data
    out = tmp_path / "run"
    ran = sg.evaluate(dataset, scenes, "forward", out, split="train", sensors=[],
                      config={"task": {"max_steps": 9}})
    record = json.loads((out / "sage3d_run.json").read_text())
    assert record["env"]["task"]["max_steps"] == 9 and record["settings"]["preset"] == "sage"
    files = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    # Other overrides are another environment: refused, naming what differs, nothing written.
    with pytest.raises(ValueError, match=re.escape(
            "this run folder holds a run with another environment "
            "(env.task.max_steps: 9 recorded, 12 asked); use a new run folder")):
        sg.evaluate(dataset, scenes, "forward", out, split="train", sensors=[],
                    config={"task": {"max_steps": 12}})
    # So is the preset's own (`sage3d eval`'s) environment.
    with pytest.raises(ValueError, match=re.escape("env.task.max_steps: 9 recorded, 500 asked")):
        sg.evaluate(dataset, scenes, "forward", out, split="train")
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == files
    # The same overrides resume.
    again = sg.evaluate(dataset, scenes, "forward", out, split="train", sensors=[],
                        config={"task": {"max_steps": 9}})
    assert again["resumed"] == ran["total"] and again["ran"] == 0


class Forward:
    """FORWARD until the step limit, as `--agent forward`; counts what it saw."""

    name = "forward"

    def __init__(self):
        self.episode = None
        self.seen = 0

    def reset(self, episode):
        self.episode = episode["id"]
        self.seen = 0

    def act(self, obs):
        assert self.episode is not None and isinstance(obs["instruction"], str)
        assert obs["pose"].shape == (4,)
        self.seen += 1
        return 1


def test_a_python_agent_gives_the_cli_records_of_the_same_policy(data, sage3d, tmp_path):
    scenes, dataset = data
    expected = cli_eval(sage3d, data, "forward", tmp_path / "cli", split="test_balanced")
    sg.evaluate(dataset, scenes, Forward(), tmp_path / "py", split="test_balanced", sensors=[])
    got = sorted(jsonl(tmp_path / "py" / "episodes.jsonl"), key=lambda r: r["episode_id"])
    assert got == expected
    assert (tmp_path / "py" / "summary.json").read_bytes() == (tmp_path / "cli" / "summary.json").read_bytes()


class Seer:
    """Reads the images it is given: turns left while the centre pixel is near, else forward,
    and stops after 5 steps."""

    def __init__(self):
        self.steps = 0

    def act(self, obs):
        assert obs["rgb"].shape == (12, 16, 3) and obs["depth"].shape == (12, 16)
        self.steps += 1
        if self.steps > 5:
            return 0
        return 2 if obs["depth"][6, 8] < 0.5 else 1


def test_python_agents_see_images_and_their_errors_are_recorded(data, tmp_path):
    scenes, dataset = data
    r = sg.evaluate(dataset, scenes, Seer, tmp_path / "seer", split="test_balanced", width=16, height=12)
    recs = jsonl(tmp_path / "seer" / "episodes.jsonl")
    assert r["summary"]["agent"] == "Seer" and {x["agent"] for x in recs} == {"Seer"}
    assert all(x["termination"] == "stop" and len(x["record"]["steps"]) == 6 for x in recs)

    class Broken:
        def act(self, obs):
            raise RuntimeError("no idea")

    with pytest.warns(RuntimeWarning, match="every episode of the run faulted"):
        r = sg.evaluate(dataset, scenes, Broken(), tmp_path / "broken", split="test_balanced", sensors=[])
    recs = jsonl(tmp_path / "broken" / "episodes.jsonl")
    assert len(r["summary"]["failed"]) == len(recs) > 0
    assert all("no idea" in x["error"] and x["failure"] == "episode_error" for x in recs)
    assert r["summary"]["failures"] == {"episode_error": len(recs)}
    # strict: the same run (resumed from its folder) raises, as `sage3d eval --strict` exits 1.
    with pytest.raises(ValueError, match=f"every episode of the run faulted \\({len(recs)}\\)"):
        sg.evaluate(dataset, scenes, Broken(), tmp_path / "broken", split="test_balanced", sensors=[], strict=True)


def test_evaluated_agents_are_offered_what_sage_env_offers(data, tmp_path):
    scenes, dataset = data

    class TiltUp:
        def act(self, obs):
            return 4

    # LOOK_UP is not among SageEnv's default Discrete(4): an agent answering it faults.
    with pytest.warns(RuntimeWarning, match="every episode of the run faulted"):
        sg.evaluate(dataset, scenes, TiltUp, tmp_path / "tilt", split="test_balanced", sensors=[])
    recs = jsonl(tmp_path / "tilt" / "episodes.jsonl")
    assert recs and all("camera tilt" in x["error"] for x in recs)
    # Something that is no agent at all is refused before any episode.
    with pytest.raises(TypeError, match="agent: expected"):
        sg.evaluate(dataset, scenes, 123, tmp_path / "number", split="test_balanced")
    assert not (tmp_path / "number").exists()
    with pytest.raises(TypeError, match="scenes_only: expected a list"):
        sg.evaluate(dataset, scenes, "forward", tmp_path / "one", scenes_only="home7")


class Interrupter:
    """Presses Ctrl-C (SIGINT to this process) on the first action of the first run; every
    agent of that run then waits until Python has handled it (`handled`) before it stops, so
    no episode can end before the run sees the interrupt."""

    armed = True
    handled = threading.Event()

    def act(self, obs):
        if Interrupter.armed:
            Interrupter.armed = False
            signal.raise_signal(signal.SIGINT)
        Interrupter.handled.wait()
        return 0


def test_ctrl_c_stops_an_evaluation_which_then_resumes(data, tmp_path):
    scenes, dataset = data
    run = tmp_path / "run"

    def on_interrupt(signum, frame):
        Interrupter.handled.set()
        raise KeyboardInterrupt

    default = signal.signal(signal.SIGINT, on_interrupt)
    try:
        with pytest.raises(KeyboardInterrupt):
            sg.evaluate(dataset, scenes, Interrupter, run, split="test_balanced", sensors=[])
    finally:
        signal.signal(signal.SIGINT, default)
    # Stopped: only the episodes in flight when Ctrl-C came were recorded (one per thread at
    # most), and no summary was written, as a killed run leaves none.
    recorded = len(jsonl(run / "episodes.jsonl"))
    summarised = (run / "summary.json").exists()
    assert 1 <= recorded <= (os.cpu_count() or 1)
    # The same run resumes from them.
    r = sg.evaluate(dataset, scenes, Interrupter, run, split="test_balanced", sensors=[])
    assert r["resumed"] == recorded and r["resumed"] + r["ran"] == r["total"]
    assert summarised == (recorded == r["total"])
    if r["total"] > (os.cpu_count() or 1):
        assert not summarised


class Looker:
    """FORWARD three times, then STOP, checking it is shown the colour image."""

    def __init__(self):
        self.steps = 0

    def act(self, obs):
        assert obs["rgb"].shape == (12, 16, 3) and obs["rgb"].dtype == np.uint8
        self.steps += 1
        return 0 if self.steps > 3 else 1


def test_evaluation_renders_on_the_device_asked_for(data, tmp_path):
    scenes, dataset = data
    records = {}
    for device in ("cpu", "gpu"):
        sg.evaluate(dataset, scenes, Looker, tmp_path / device, split="test_balanced", width=16,
                    height=12, sensors=["rgb"], device=device)
        records[device] = jsonl(tmp_path / device / "episodes.jsonl")
    # The policy does not depend on the pixels: the same records on either device.
    assert records["cpu"] == records["gpu"] and records["cpu"]
    # The run record names a device other than the CPU (a CPU run's record is as before).
    def settings(device):
        return json.loads((tmp_path / device / "sage3d_run.json").read_text())["settings"]

    assert settings("gpu")["device"] == "gpu" and "device" not in settings("cpu")
    with pytest.raises(ValueError, match="cpu, gpu, auto"):
        sg.evaluate(dataset, scenes, Looker, tmp_path / "bad", device="tpu")
