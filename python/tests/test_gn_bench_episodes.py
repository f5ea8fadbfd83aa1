"""GN-Bench episode splits in and out: `sage3d data import FILE.parquet --gn-bench` and
`sage3d data export DATASET --format gn-bench`.

The split is computed here, independently of sage3d, from the research notes' mapping: GN-Bench's
pixel of a point (x, y) of its world is col = round((-x - lower_x)/s - 0.5), row = round((y +
upper_y)/s - 0.5) with `lower`/`upper` from occupancy.json and s = (upper - lower) / image size;
InteriorGS puts pixel (col, row) at W = (upper_x - s*(col + 0.5), lower_y + s*(row + 0.5)).
"""

import json
import math

import numpy as np
import pytest
from PIL import Image

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")
pd = pytest.importorskip("pandas")

SCENE = "home"


@pytest.fixture(scope="module")
def scenes(tmp_path_factory, sage3d):
    """A folder holding one small synthetic home."""
    root = tmp_path_factory.mktemp("gn") / "scenes"
    sage3d("scene", "synth", "--seed", 5, "--out", root / SCENE, "--rooms", 3, "--objects", 20,
           "--gaussians", 5000)
    assert (root / SCENE / "occupancy.json").is_file() and (root / SCENE / "occupancy.png").is_file()
    return root


def occupancy(scenes):
    meta = json.loads((scenes / SCENE / "occupancy.json").read_text())
    img = np.asarray(Image.open(scenes / SCENE / "occupancy.png").convert("L"))
    lower, upper = np.array(meta["lower"][:2], float), np.array(meta["upper"][:2], float)
    h, w = img.shape
    s = (upper - lower) / np.array([w, h], float)
    return img, lower, upper, s


def gn_point(col, row, lower, upper, s):
    """GN world point whose GN pixel is (col, row): the research mapping solved for x, y."""
    return -(lower[0] + s[0] * (col + 0.5)), s[1] * (row + 0.5) - upper[1]


def gn_pixel(x, y, lower, upper, s):
    return int(round((-x - lower[0]) / s[0] - 0.5)), int(round((y + upper[1]) / s[1] - 0.5))


def w_of_pixel(col, row, lower, upper, s):
    """InteriorGS's own placement of a pixel's centre (column 0 at max-x, row 0 at min-y)."""
    return upper[0] - s[0] * (col + 0.5), lower[1] + s[1] * (row + 0.5)


def free_runs(img, length, clearance):
    """Rows and first columns of horizontal runs of `length` free pixels with `clearance`
    free pixels all around them."""
    free = img >= 200
    h, w = free.shape
    out = []
    for r in range(clearance, h - clearance):
        for c in range(clearance, w - length - clearance, 3):
            if free[r - clearance:r + clearance + 1, c - clearance:c + length + clearance].all():
                out.append((r, c))
                break
    return out


@pytest.fixture(scope="module")
def split(scenes):
    """A GN-Bench split of four rows on free ground; row 3's pixels are shifted by three."""
    img, lower, upper, s = occupancy(scenes)
    length = int(round(1.5 / s[0]))
    runs = free_runs(img, length, clearance=int(math.ceil(0.4 / s[0])))
    assert len(runs) >= 4, "the synthetic home has room for four straight paths"
    runs = runs[:: max(1, len(runs) // 4)][:4]
    labels = json.loads((scenes / SCENE / "labels.json").read_text())
    objects = labels["labels"] if isinstance(labels, dict) else labels
    first = next(o for o in objects if "bounding_box" in o)
    rows = []
    for k, (r, c0) in enumerate(runs):
        # Row k walks west to east in W: along increasing W x, i.e. decreasing column.
        cols = list(range(c0 + length - 1, c0 - 1, -1))
        pts = [gn_point(c, r, lower, upper, s) for c in cols]
        px = [gn_pixel(x, y, lower, upper, s) for x, y in pts]
        assert [p[0] for p in px] == cols and all(p[1] == r for p in px)
        if k == 2:
            px = [(c + 3, rr) for c, rr in px]
        heading = 0.0 if k != 1 else 90.0
        rows.append({
            "scene": SCENE,
            "trajectory_id": str(10 + k),
            "instruction": f"walk ahead {k}",
            "grounded_instruction": f"walk ahead to the {first['label']} {k}",
            "label_ins_id": str(first["ins_id"]) if k == 0 else "999999",
            "label_label": first["label"] if k == 0 else "Thing",
            "label_goal_pixel_x": px[-1][0],
            "label_goal_pixel_y": px[-1][1],
            "start_world_x": pts[0][0],
            "start_world_y": pts[0][1],
            "goal_world_x": pts[-1][0],
            "goal_world_y": pts[-1][1],
            "start_facing_unit_dx": math.cos(math.radians(heading)),
            "start_facing_unit_dy": math.sin(math.radians(heading)),
            "start_facing_heading_degrees": heading,
            "path_raster_world_x": [p[0] for p in pts],
            "path_raster_world_y": [p[1] for p in pts],
            "path_raster_pixel_x": [p[0] for p in px],
            "path_raster_pixel_y": [p[1] for p in px],
        })
    return pd.DataFrame(rows), (lower, upper, s), runs, cols_of(runs, length)


def cols_of(runs, length):
    return [list(range(c0 + length - 1, c0 - 1, -1)) for _, c0 in runs]


def jsonl(path):
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


@pytest.fixture(scope="module")
def imported(tmp_path_factory, sage3d, scenes, split):
    df = split[0]
    tmp = tmp_path_factory.mktemp("imp")
    df.to_parquet(tmp / "split.parquet")
    data = tmp / "data"
    proc = sage3d("data", "import", tmp / "split.parquet", "--gn-bench", "--scenes", scenes,
                  "--out", data, "--split", "test")
    return data, proc, tmp / "split.parquet"


def test_import_converts_to_w_and_reports_the_mismatched_row(imported, split):
    data, proc, _ = imported
    df, (lower, upper, s), runs, cols = split
    eps = jsonl(data / "episodes" / "test.jsonl")
    assert [e["episode_id"] for e in eps] == ["home_10", "home_11", "home_13"]
    assert [e["trajectory_id"] for e in eps] == [10, 11, 13]
    for e, k in zip(eps, [0, 1, 3]):
        r = runs[k][0]
        # Every path point is the centre of its pixel as InteriorGS places it.
        want = [w_of_pixel(c, r, lower, upper, s) for c in cols[k]]
        np.testing.assert_allclose([p[:2] for p in e["reference_path"]], want, atol=1e-4)
        assert all(p[2] == 0.0 for p in e["reference_path"])
        np.testing.assert_allclose(e["start"]["position"], [*want[0], 0.0], atol=1e-4)
        np.testing.assert_allclose(e["goal"]["position"], [*want[-1], 0.0], atol=1e-4)
        # The path runs along +x in W, as its columns fall.
        assert e["reference_path"][-1][0] > e["reference_path"][0][0]
        assert e["instruction"] == df["grounded_instruction"][k]
        assert e["instruction_texts"] == {"grounded": df["grounded_instruction"][k],
                                          "plain": df["instruction"][k]}
        assert e["actions"][-1] == 0 and e["path_length"] == pytest.approx(s[0] * (len(cols[k]) - 1), abs=1e-3)
    assert eps[0]["start"]["yaw"] == pytest.approx(0.0, abs=1e-6)
    assert eps[1]["start"]["yaw"] == pytest.approx(math.pi / 2, abs=1e-6)
    # Facing +y, the first action turns right (clockwise) to walk along +x.
    assert eps[1]["actions"][0] == 3
    assert eps[0]["goal"]["kind"] == "object" and eps[0]["goal"]["ref"] != "999999"
    assert eps[1]["goal"] == {"ref": "999999", "kind": "pose", "position": eps[1]["goal"]["position"]}
    report = json.loads((data / "import_reports" / "test.json").read_text())
    assert report["rows"] == 4 and report["imported"] == 3 and report["instruction"] == "grounded"
    assert report["episode_rows"] == {"home_10": 1, "home_11": 2, "home_13": 4}
    [bad] = report["rejected"]
    assert bad["row"] == 3 and bad["column"] == "path_raster_pixel_x" and bad["episode_id"] == "home_12"
    assert "rejected row 3 (home_12, path_raster_pixel_x)" in proc.stderr
    assert "3 rows imported, 1 rejected" in proc.stderr
    splits = json.loads((data / "splits.json").read_text())
    assert "test" in splits["splits"]


def test_the_plain_instruction_on_request(tmp_path, sage3d, scenes, imported):
    _, _, file = imported
    sage3d("data", "import", file, "--gn-bench", "--scenes", scenes, "--out", tmp_path / "d",
           "--split", "p", "--instruction", "plain")
    eps = jsonl(tmp_path / "d" / "episodes" / "p.jsonl")
    assert eps[0]["instruction"] == "walk ahead 0"
    assert eps[0]["instruction_texts"]["grounded"].startswith("walk ahead to the ")


@pytest.mark.parametrize("case", ["missing", "unequal", "nan", "nan_kept", "scene"])
def test_bad_files_name_the_row_and_column(tmp_path, sage3d, scenes, split, case):
    df = split[0].iloc[[0, 1]].reset_index(drop=True).copy()
    if case == "missing":
        df = df.drop(columns=["goal_world_y"])
        want = ["goal_world_y", "missing column"]
    elif case == "unequal":
        df["path_raster_pixel_y"] = [v if i != 1 else v[:-1] for i, v in enumerate(df["path_raster_pixel_y"])]
        want = ["row 2.path_raster_pixel_y", "equal lengths"]
    elif case == "nan":
        # pandas writes a NaN as null.
        df.loc[1, "start_world_x"] = float("nan")
        want = ["row 2.start_world_x", "null: expected a finite number"]
    elif case == "nan_kept":
        # A NaN kept as NaN (pyarrow without pandas' null conversion), inside a path list.
        df["path_raster_world_y"] = [v if i != 1 else [*v[:4], float("nan"), *v[5:]]
                                     for i, v in enumerate(df["path_raster_world_y"])]
        want = ["row 2.path_raster_world_y", "element 4: NaN: expected a finite number"]
    else:
        df["scene"] = "elsewhere"
        want = ["row 1.scene", "scene 'elsewhere' is not in the scenes folder", "2 of 2 rejected"]
    if case == "nan_kept":
        table = pa.Table.from_pandas(df, preserve_index=False)
        k = table.column_names.index("path_raster_world_y")
        col = pa.array(list(df["path_raster_world_y"]), type=pa.list_(pa.float64()), from_pandas=False)
        pq.write_table(table.set_column(k, "path_raster_world_y", col), tmp_path / "bad.parquet")
    else:
        df.to_parquet(tmp_path / "bad.parquet")
    proc = sage3d("data", "import", tmp_path / "bad.parquet", "--gn-bench", "--scenes", scenes,
                  "--out", tmp_path / "d", check=False)
    assert proc.returncode != 0
    for w in want:
        assert w in proc.stderr, proc.stderr
    assert not (tmp_path / "d" / "episodes").exists()


def test_export_reads_in_pyarrow_and_reimports_equal(tmp_path, sage3d, scenes, imported, split):
    data, _, _ = imported
    df = split[0]
    out = tmp_path / "out.parquet"
    sage3d("data", "export", data, "--format", "gn-bench", "--split", "test", "--out", out)
    table = pq.read_table(out)
    types = {f.name: str(f.type) for f in table.schema}
    assert types["scene"] == "string" and types["label_goal_pixel_x"] == "int64"
    assert types["start_world_x"] == "double" and types["start_facing_heading_degrees"] == "double"
    assert types["path_raster_world_x"].startswith("list<") and "double" in types["path_raster_world_x"]
    assert types["path_raster_pixel_y"].startswith("list<") and "int64" in types["path_raster_pixel_y"]
    assert list(table.column_names) == list(df.columns)
    got = table.to_pandas()
    want = df.iloc[[0, 1, 3]].reset_index(drop=True)
    for col in ["scene", "trajectory_id", "instruction", "grounded_instruction", "label_goal_pixel_x",
                "label_goal_pixel_y"]:
        assert list(got[col]) == list(want[col]), col
    assert got["label_ins_id"][0] == want["label_ins_id"][0] and got["label_label"][0] == want["label_label"][0]
    for col in ["start_world_x", "start_world_y", "goal_world_x", "goal_world_y",
                "start_facing_heading_degrees", "start_facing_unit_dx", "start_facing_unit_dy"]:
        np.testing.assert_allclose(got[col], want[col], atol=1e-5, err_msg=col)
    for col in ["path_raster_pixel_x", "path_raster_pixel_y"]:
        assert [list(v) for v in got[col]] == [list(v) for v in want[col]], col
    for col in ["path_raster_world_x", "path_raster_world_y"]:
        for a, b in zip(got[col], want[col]):
            np.testing.assert_allclose(a, b, atol=1e-5)
    # An existing file is kept unless --force.
    again = sage3d("data", "export", data, "--split", "test", "--out", out, check=False)
    assert again.returncode != 0 and "exists" in again.stderr
    # A name that says another format is refused: readers tell the format by it.
    csv = sage3d("data", "export", data, "--split", "test", "--out", tmp_path / "out.csv", check=False)
    assert csv.returncode != 0 and "must end in .parquet" in csv.stderr, csv.stderr
    assert not (tmp_path / "out.csv").exists()
    sage3d("data", "import", out, "--gn-bench", "--scenes", scenes, "--out", tmp_path / "re",
           "--split", "test")
    assert (tmp_path / "re" / "episodes" / "test.jsonl").read_text() == \
        (data / "episodes" / "test.jsonl").read_text()


def test_imported_episodes_run_in_eval(tmp_path, sage3d, imported):
    data, _, _ = imported
    # The import recorded its scenes folder, so eval finds it.
    sage3d("eval", data, "--agent", "oracle", "--split", "test", "--out", tmp_path / "run")
    runs = jsonl(tmp_path / "run" / "episodes.jsonl")
    assert sorted(r["episode_id"] for r in runs) == ["home_10", "home_11", "home_13"]
    assert all(not r.get("error") and r.get("metrics") for r in runs), runs
