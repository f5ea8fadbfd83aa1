"""The pipelines from Python are the command line's: `sage3d.demo` and `sage3d.build_dataset`
write the same files, byte for byte, as `sage3d demo` and `sage3d data build` with the same
settings (every file except the run records, which name their output folder)."""

import pathlib

import sage3d as sg


def tree(root: pathlib.Path) -> dict:
    """Every file under `root` with its bytes, keyed by relative path, run records and caches
    left out (they hold paths or are shared between runs)."""
    return {
        str(p.relative_to(root)): p.read_bytes()
        for p in sorted(root.rglob("*"))
        if p.is_file() and p.name != "sage3d_run.json" and ".sage3d" not in p.parts
    }


def test_demo_from_python_writes_what_the_command_line_writes(tmp_path, sage3d):
    settings = dict(scenes=1, seed=4, per_scene=3, gaussians=3000, agents=["oracle", "forward"],
                    split="train")
    summaries = sg.demo(tmp_path / "py", **settings)
    assert sorted(summaries) == ["forward", "oracle"]
    assert summaries["oracle"]["overall"]["episodes"] > 0
    assert summaries["oracle"]["overall"]["means"]["sr"] == 1.0
    sage3d("demo", "--out", tmp_path / "cli", "--scenes", 1, "--seed", 4, "--per-scene", 3,
           "--gaussians", 3000, "--agents", "oracle,forward", "--split", "train")
    py, cli = tree(tmp_path / "py"), tree(tmp_path / "cli")
    assert "overview.png" in py and "runs/oracle/report.html" in py
    assert py.keys() == cli.keys()
    # An evaluation appends each record as its episode finishes, so only the set of lines is
    # fixed; its summary is the same bytes.
    def lines(k):
        return sorted(py[k].splitlines()), sorted(cli[k].splitlines())

    records = [k for k in py if k.startswith("runs/") and k.endswith("episodes.jsonl")]
    assert len(records) == 2 and all(a == b for a, b in map(lines, records))
    differ = [k for k in py if py[k] != cli[k] and not k.endswith((".html", ".json"))]
    assert differ == [] or set(differ) <= set(records)
    for k in ("dataset/summary.json", "runs/oracle/summary.json", "runs/forward/summary.json"):
        assert py[k] == cli[k], k


def test_build_dataset_from_python_equals_data_build(tmp_path, sage3d, small_scene):
    summary = sg.build_dataset(small_scene, tmp_path / "py", per_scene=3, seed=2, balanced=4)
    sage3d("data", "build", small_scene, "--out", tmp_path / "cli", "--per-scene", 3, "--seed", 2,
           "--balanced", 4)
    assert tree(tmp_path / "py") == tree(tmp_path / "cli")
    assert summary["episodes"] > 0
