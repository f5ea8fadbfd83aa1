"""python/tools/coacd_cache.py against sage3d: the files its writer makes are read as hulls, and
it takes as whole exactly the entries sage3d reads, so a damaged one is listed and made again."""

import importlib.util
import json
import pathlib


def test_coacd_cache_files_are_read_by_sage3d(small_scene, sage3d, tmp_path):
    """The CoACD tool's writer makes files sage3d accepts. CoACD itself is optional, so each
    pending mesh gets one stand-in hull (its axis-aligned box) through the tool's encoder; then
    `physics build --backend coacd` reads every entry from the cache and nothing is pending."""
    spec = importlib.util.spec_from_file_location(
        "coacd_cache", pathlib.Path(__file__).resolve().parents[1] / "tools" / "coacd_cache.py"
    )
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    cache = tmp_path / "hulls"
    todo = tmp_path / "todo.json"
    args = ["--backend", "coacd", "--cache", cache]
    assert sage3d("physics", "build", small_scene, *args, check=False).returncode != 0
    sage3d("physics", "pending", small_scene, *args, "--out", todo)
    pending = json.loads(todo.read_text())
    assert pending["decomposer"].startswith("coacd;") and pending["meshes"]
    for m in pending["meshes"]:
        lo = [min(v[k] for v in m["vertices"]) for k in range(3)]
        hi = [max(v[k] for v in m["vertices"]) for k in range(3)]
        corners = [[(lo, hi)[(i >> k) & 1][k] for k in range(3)] for i in range(8)]
        faces = [[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4],
                 [2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]]
        tool.write_atomic(m["cache_file"], tool.encode(m["key"], [(corners, faces)]))
    report = json.loads(sage3d("physics", "build", small_scene, *args, "--json").stdout)
    assert report["cached"] == len(pending["meshes"]) and report["decomposed"] == 0
    assert all(o["hulls"] == 1 and o["source"] == "cached" for o in report["objects"])
    again = tmp_path / "again.json"
    sage3d("physics", "pending", small_scene, *args, "--out", again)
    assert json.loads(again.read_text())["meshes"] == []
    # An entry cut short: the build names it, `pending` lists it alone again, and the tool,
    # which skips whole entries when it resumes, takes it as one to make.
    damaged = pending["meshes"][0]
    entry = pathlib.Path(damaged["cache_file"])
    entry.write_bytes(entry.read_bytes()[:-4])
    failed = sage3d("physics", "build", small_scene, *args, check=False)
    assert failed.returncode != 0 and str(entry) in failed.stderr, failed.stderr
    assert "cannot be read" in failed.stderr, failed.stderr
    sage3d("physics", "pending", small_scene, *args, "--out", again, "--force")
    assert [m["key"] for m in json.loads(again.read_text())["meshes"]] == [damaged["key"]]
    assert not tool.is_whole_entry(entry, damaged["key"])
    assert all(tool.is_whole_entry(m["cache_file"], m["key"]) for m in pending["meshes"][1:])
    assert not tool.is_whole_entry(pending["meshes"][1]["cache_file"], damaged["key"])
    # The tool takes as whole exactly what sage3d reads: entries that are whole in their
    # layout but hold a value sage3d refuses are listed again and made again.
    box = lambda v: (v, [[0, 1, 2], [0, 2, 3], [0, 3, 1], [1, 3, 2]])  # noqa: E731
    corners = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    tool.write_atomic(str(entry), tool.encode(damaged["key"], [box(corners)]))
    assert tool.is_whole_entry(entry, damaged["key"])
    sage3d("physics", "pending", small_scene, *args, "--out", again, "--force")
    assert json.loads(again.read_text())["meshes"] == []
    for what, data in [
        ("a coordinate that is not finite", tool.encode(damaged["key"], [box([[float("nan")] * 3] + corners[1:])])),
        ("a triangle index past the vertices", tool.encode(damaged["key"], [(corners, [[0, 1, 4]])])),
        ("a trailing byte", tool.encode(damaged["key"], [box(corners)]) + b"\0"),
    ]:
        entry.write_bytes(data)
        sage3d("physics", "pending", small_scene, *args, "--out", again, "--force")
        listed = [m["key"] for m in json.loads(again.read_text())["meshes"]]
        assert listed == [damaged["key"]], what
        assert not tool.is_whole_entry(entry, damaged["key"]), what
