"""`sage3d data render --format lerobot`: a LeRobot dataset of codebase version v3.0, checked
against the format with pyarrow, pandas and NumPy alone (no lerobot package): info.json and the
Parquet schemas agree, indices are contiguous, each episode is one row group of one file, the
task table has `task` as its pandas index, every statistic is what the data gives, frames are
PNGs of the render's size, the extrinsic is the camera's pose above the agent's, `nav_delta`
is the step between consecutive poses, the action is one-hot beside its code; the bytes do not
depend on the thread count and a dataset cut short is redone to the same bytes. Where the
`lerobot` package is installed (CI does not: it brings torch), its own loader and normaliser
read the dataset too."""

import io
import json
import math
import shutil

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from PIL import Image

from conftest import write_split

W, H = 40, 30
EYE = 1.2  # the wheeled robot's camera height
STEP, TURN = 0.35, 30.0  # navila_small
WORDS = {0: "stop", 1: f"move forward {STEP} meter", 2: f"turn left {TURN:g} degree",
         3: f"turn right {TURN:g} degree"}
STATS = ("min", "max", "mean", "std", "q01", "q10", "q50", "q90", "q99")
QUANT = {"q01": 0.01, "q10": 0.10, "q50": 0.50, "q90": 0.90, "q99": 0.99}


@pytest.fixture(scope="module")
def data(tmp_path_factory, sage3d):
    """Two synthetic homes and a dataset with a split `few` of five VLN episodes: per scene two
    sharing one route (one walk, two episodes) and one more. Returns (scenes, dataset)."""
    root = tmp_path_factory.mktemp("lerobot")
    scenes = root / "scenes"
    for seed in (21, 22, 23):
        sage3d("scene", "synth", "--seed", seed, "--out", scenes / f"home{seed}", "--rooms", 3,
               "--objects", 25, "--gaussians", 1500)
    dataset = root / "dataset"
    sage3d("data", "build", scenes, "--out", dataset, "--per-scene", 3, "--seed", 7,
           "--balanced", 6, "--scene-unseen", 0, "--val", 0)
    routes = {}
    for line in (dataset / "episodes" / "train.jsonl").read_text().splitlines():
        ep = json.loads(line)
        if ep["task"] == "vln" and len(ep["reference_path"]) >= 2:
            routes.setdefault(ep["scene"], {}).setdefault(json.dumps(ep["reference_path"]), []).append(line)
    few = []
    for by_path in list(routes.values())[:2]:
        first, second = list(by_path.values())[:2]
        few += first[:2] + second[:1]
    assert len(few) == 6
    write_split(dataset, "few", few[:5])
    return scenes, dataset


def render(sage3d, data, out, threads=1, check=True):
    scenes, dataset = data
    return sage3d("--threads", threads, "data", "render", dataset, "--scenes", scenes, "--out", out,
                  "--split", "few", "--width", W, "--height", H, "--sensors", "rgb,depth",
                  "--keep-failed", "--format", "lerobot", check=check)


@pytest.fixture(scope="module")
def ds(data, sage3d, tmp_path_factory):
    out = tmp_path_factory.mktemp("render") / "one"
    render(sage3d, data, out)
    return out


def tree(root):
    """Every file under `root` but the run record: {relative path: bytes}."""
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file() and p.name != "sage3d_run.json"}


def info(ds):
    return json.loads((ds / "meta" / "info.json").read_text())


def frames(ds):
    """All data files as one table, in file order."""
    files = sorted((ds / "data").glob("*/*.parquet"))
    return pa.concat_tables(pq.read_table(f) for f in files)


def column(table, name, shape):
    """A feature's column as a float64 (or string) NumPy array of shape [frames, *shape]."""
    col = table.column(name).combine_chunks()
    for _ in shape if shape != [1] else []:
        col = col.flatten()
    if pa.types.is_string(col.type):
        return np.array(col.to_pylist())
    return col.to_numpy().astype(np.float64).reshape(len(table), *shape)


def arrow_type(feature):
    dtype, shape = feature["dtype"], feature["shape"]
    if dtype == "image":
        return pa.struct([("bytes", pa.binary()), ("path", pa.string())])
    scalar = {"float32": pa.float32(), "int64": pa.int64(), "string": pa.string()}[dtype]
    if shape == [1]:
        return scalar
    if len(shape) == 1:
        return pa.list_(scalar, shape[0])
    t = scalar
    for _ in shape:
        t = pa.list_(t)
    return t


def test_info_and_schemas_agree(ds):
    meta = info(ds)
    assert meta["codebase_version"] == "v3.0"
    for key in ("robot_type", "fps", "total_episodes", "total_frames", "total_tasks", "chunks_size",
                "data_files_size_in_mb", "video_files_size_in_mb", "data_path", "video_path",
                "splits", "features"):
        assert key in meta, key
    assert isinstance(meta["fps"], int) and meta["video_path"] is None
    assert meta["splits"] == {"few": f"0:{meta['total_episodes']}"}
    assert meta["robot_type"] == "wheeled" and meta["chunks_size"] == 1000
    feats = meta["features"]
    for name in ("timestamp", "frame_index", "episode_index", "index", "task_index"):
        assert feats[name]["shape"] == [1] and feats[name]["names"] is None
    assert feats["observation.images.rgb"] == {"dtype": "image", "shape": [H, W, 3],
                                               "names": ["height", "width", "channel"]}
    assert feats["observation.depth"]["shape"] == [H, W, 1]
    assert feats["observation.camera_extrinsic"]["shape"] == [4, 4]
    assert feats["action"] == {"dtype": "float32", "shape": [4],
                               "names": ["stop", "move_forward", "turn_left", "turn_right"]}
    assert feats["annotation.action_id"] == {"dtype": "int64", "shape": [1], "names": None}
    # What LeRobot's policies take (every feature named `observation…` or `action…`) is float
    # or an image: its normaliser casts the statistics to the feature's dtype, so an integer
    # feature's mean and std would be truncated. An action of shape [1] would load as a scalar.
    for name, f in feats.items():
        if name.startswith(("observation", "action")):
            assert f["dtype"] in ("float32", "image"), name
    assert feats["action"]["shape"] != [1]
    files = sorted((ds / "data").glob("*/*.parquet"))
    assert [f.relative_to(ds).as_posix() for f in files] == ["data/chunk-000/file-000.parquet"]
    for f in files:
        schema = pq.read_schema(f)
        assert set(schema.names) == set(feats), f
        for name, feat in feats.items():
            assert schema.field(name).type == arrow_type(feat), name
        assert pq.ParquetFile(f).metadata.row_group(0).column(0).compression == "SNAPPY"
    # Nothing but the dataset, the manifest and the run record: the frames are inside.
    assert not (ds / "images").exists()
    assert sorted(p.name for p in ds.iterdir()) == ["data", "manifest.json", "meta", "sage3d_run.json"]


def test_indices_episodes_and_row_groups(ds, data):
    meta = info(ds)
    t = frames(ds)
    n = meta["total_frames"]
    assert len(t) == n
    index = t.column("index").to_numpy()
    assert (index == np.arange(n)).all()
    ep = t.column("episode_index").to_numpy()
    fi = t.column("frame_index").to_numpy()
    ts = t.column("timestamp").to_numpy()
    assert ts.dtype == np.float32
    assert (ts == (fi / meta["fps"]).astype(np.float32)).all()
    episodes = pq.read_table(ds / "meta" / "episodes" / "chunk-000" / "file-000.parquet").to_pandas()
    assert list(episodes["episode_index"]) == list(range(meta["total_episodes"]))
    assert meta["total_episodes"] == 5
    for _, e in episodes.iterrows():
        rows = np.flatnonzero(ep == e["episode_index"])
        assert rows[0] == e["dataset_from_index"] and rows[-1] + 1 == e["dataset_to_index"]
        assert len(rows) == e["length"] == e["dataset_to_index"] - e["dataset_from_index"]
        assert (fi[rows] == np.arange(len(rows))).all(), "frame_index restarts per episode"
        path = ds / "data" / f"chunk-{e['data/chunk_index']:03d}" / f"file-{e['data/file_index']:03d}.parquet"
        assert e["episode_index"] in pq.read_table(path, columns=["episode_index"]).column(0).to_pylist()
        assert (e["meta/episodes/chunk_index"], e["meta/episodes/file_index"]) == (0, 0)
    # One row group per episode, in order.
    f = pq.ParquetFile(ds / "data" / "chunk-000" / "file-000.parquet")
    assert f.num_row_groups == meta["total_episodes"]
    for g in range(f.num_row_groups):
        assert set(f.read_row_group(g, columns=["episode_index"]).column(0).to_pylist()) == {g}
    # Episode ids and scenes are the split's, in scene order.
    few = [json.loads(line) for line in (data[1] / "episodes" / "few.jsonl").read_text().splitlines()]
    assert sorted(episodes["episode_id"]) == sorted(e["episode_id"] for e in few)
    assert list(episodes["scene"]) == sorted(episodes["scene"])
    by_id = {e["episode_id"]: e for e in few}
    for _, e in episodes.iterrows():
        assert list(e["tasks"]) == [by_id[e["episode_id"]]["instruction"]]
        assert e["scene"] == by_id[e["episode_id"]]["scene"]


def test_task_table_is_indexed_by_task(ds):
    tasks = pd.read_parquet(ds / "meta" / "tasks.parquet")
    assert tasks.index.name == "task"
    assert list(tasks["task_index"]) == list(range(len(tasks)))
    assert len(tasks) == info(ds)["total_tasks"]
    # LeRobot's lookup: row `task_index` of the table names the task.
    episodes = pq.read_table(ds / "meta" / "episodes" / "chunk-000" / "file-000.parquet").to_pandas()
    t = frames(ds)
    for _, e in episodes.iterrows():
        rows = t.slice(e["dataset_from_index"], e["length"])
        for k in set(rows.column("task_index").to_pylist()):
            assert tasks.iloc[k].name == e["tasks"][0]


def test_every_statistic_is_the_datas(ds):
    meta = info(ds)
    stats = json.loads((ds / "meta" / "stats.json").read_text())
    t = frames(ds)
    n = len(t)
    for name, feat in meta["features"].items():
        if feat["dtype"] == "string":
            assert name not in stats
            continue
        s = stats[name]
        assert s["count"] == [n], name
        if feat["dtype"] == "image":
            pixels = np.stack([np.asarray(Image.open(io.BytesIO(b))) for b in
                               t.column(name).combine_chunks().field("bytes").to_pylist()])
            assert pixels.shape == (n, H, W, 3)
            values = pixels.reshape(-1, 3).astype(np.float64) / 255.0
            want_shape = (3, 1, 1)
        elif name == "observation.depth":
            values = column(t, name, feat["shape"]).reshape(-1, 1)
            want_shape = (1, 1, 1)
        else:
            values = column(t, name, feat["shape"])
            want_shape = tuple(feat["shape"])
        want = {"min": values.min(axis=0), "max": values.max(axis=0), "mean": values.mean(axis=0),
                "std": values.std(axis=0)}
        want.update({k: np.quantile(values, q, axis=0) for k, q in QUANT.items()})
        for stat in STATS:
            got = np.asarray(s[stat], dtype=np.float64)
            assert got.shape == want_shape, (name, stat, got.shape)
            np.testing.assert_allclose(got.reshape(-1), np.asarray(want[stat]).reshape(-1),
                                       rtol=1e-9, atol=1e-9, err_msg=f"{name} {stat}")
        if feat["dtype"] == "image":
            assert 0.0 <= min(np.ravel(s["min"])) and max(np.ravel(s["max"])) <= 1.0


def test_frames_poses_extrinsics_and_actions(ds, data):
    meta = info(ds)
    t = frames(ds)
    images = t.column("observation.images.rgb").combine_chunks()
    for k, b in enumerate(images.field("bytes").to_pylist()):
        assert b[:8] == b"\x89PNG\r\n\x1a\n"
        im = Image.open(io.BytesIO(b))
        assert (im.size, im.mode) == ((W, H), "RGB")
    assert images.field("path").to_pylist()[0] == "frame-000000.png"
    depth = column(t, "observation.depth", [H, W, 1])
    assert depth.max() > 0.1 and depth.min() >= 0.0  # metres
    state = column(t, "observation.state", [4])
    ext = column(t, "observation.camera_extrinsic", [4, 4])
    assert meta["features"]["observation.state"]["names"] == ["x", "y", "z", "yaw"]
    for m, (x, y, z, yaw) in zip(ext, state):
        r = m[:3, :3]
        np.testing.assert_allclose(r.T @ r, np.eye(3), atol=1e-5)
        assert abs(np.linalg.det(r) - 1) < 1e-5
        np.testing.assert_allclose(m[3], [0, 0, 0, 1])
        np.testing.assert_allclose(m[:3, 3], [x, y, z + EYE], atol=1e-5)
        # OpenCV axes: z forward along the heading, x right, y down.
        np.testing.assert_allclose(r[:, 2], [math.cos(yaw), math.sin(yaw), 0], atol=1e-5)
        np.testing.assert_allclose(r[:, 0], [math.sin(yaw), -math.cos(yaw), 0], atol=1e-5)
        np.testing.assert_allclose(r[:, 1], [0, 0, -1], atol=1e-5)
    # The floor is the episode's start height; the first frame is at the start.
    starts = {}
    for line in (data[1] / "episodes" / "few.jsonl").read_text().splitlines():
        e = json.loads(line)
        starts[e["episode_id"]] = e["start"]
    episodes = pq.read_table(ds / "meta" / "episodes" / "chunk-000" / "file-000.parquet").to_pandas()
    action = t.column("annotation.action_id").to_numpy()
    np.testing.assert_array_equal(column(t, "action", [4]), np.eye(4)[action])
    text = t.column("annotation.action_text").to_pylist()
    nav = column(t, "action.nav_delta", [3])
    for _, e in episodes.iterrows():
        a, b = e["dataset_from_index"], e["dataset_to_index"]
        start = starts[e["episode_id"]]
        np.testing.assert_allclose(state[a, :3], start["position"], atol=1e-4)
        assert (state[a:b, 2] == state[a, 2]).all()
        assert action[b - 1] == 0 and (action[a:b - 1] != 0).all(), "STOP last, only last"
        # nav_delta: the next pose in the frame of this one; STOP does not move.
        for k in range(a, b - 1):
            x, y, _, yaw = state[k]
            dx, dy = state[k + 1, 0] - x, state[k + 1, 1] - y
            want = [math.cos(yaw) * dx + math.sin(yaw) * dy, -math.sin(yaw) * dx + math.cos(yaw) * dy,
                    math.remainder(state[k + 1, 3] - yaw, 2 * math.pi)]
            np.testing.assert_allclose(nav[k], want, atol=1e-4)
        np.testing.assert_allclose(nav[b - 1], [0, 0, 0], atol=1e-6)
    for code, words, d in zip(action, text, nav):
        assert words == WORDS[code]
        if code == 2:
            assert abs(d[2] - math.radians(TURN)) < 1e-4 and abs(d[0]) < 1e-4
        if code == 3:
            assert abs(d[2] + math.radians(TURN)) < 1e-4
        if code == 1:
            assert 0 <= d[0] <= STEP + 1e-4 and abs(d[2]) < 1e-4
    assert 1 in action and ({2, 3} & set(action.tolist())), "walks move and turn"


def test_same_bytes_on_two_threads_and_after_a_cut(ds, data, sage3d, tmp_path):
    two = tmp_path / "two"
    render(sage3d, data, two, threads=2)
    assert tree(two) == tree(ds)
    # A dataset cut short (no info.json, a data file gone, no manifest) is redone to the same
    # bytes; a finished one is left as it is.
    (two / "meta" / "info.json").unlink()
    (two / "manifest.json").unlink()
    shutil.rmtree(two / "data")
    render(sage3d, data, two, threads=2)
    assert tree(two) == tree(ds)
    again = render(sage3d, data, two)
    assert "already complete" in again.stdout + again.stderr
    # The command's count of rows is info.json's.
    assert f"{info(two)['total_frames']} LeRobot rows (total_frames)" in again.stdout
    assert tree(two) == tree(ds)


def test_hugging_face_datasets_reads_it_with_lerobots_features(ds):
    """LeRobot loads the data files with `datasets`, cast to the features its
    `get_hf_features_from_features` makes of info.json (mirrored here; skipped without the
    `datasets` package, which CI does not install)."""
    datasets = pytest.importorskip("datasets")
    meta = info(ds)
    hf = {}
    for name, f in meta["features"].items():
        shape = tuple(f["shape"])
        if f["dtype"] == "image":
            hf[name] = datasets.Image()
        elif shape == (1,):
            hf[name] = datasets.Value(f["dtype"])
        elif len(shape) == 1:
            hf[name] = datasets.Sequence(length=shape[0], feature=datasets.Value(f["dtype"]))
        else:
            hf[name] = getattr(datasets, f"Array{len(shape)}D")(shape=shape, dtype=f["dtype"])
    files = [str(p) for p in sorted((ds / "data").glob("*/*.parquet"))]
    table = datasets.Dataset.from_parquet(files, features=datasets.Features(hf), cache_dir=str(ds.parent / "hf"))
    assert len(table) == meta["total_frames"]
    item = table.with_format("numpy")[1]
    assert item["observation.images.rgb"].shape == (H, W, 3)
    assert item["observation.depth"].shape == (H, W, 1)
    assert item["observation.camera_extrinsic"].shape == (4, 4)
    assert item["index"] == 1 and isinstance(table[1]["annotation.action_text"], str)


def test_lerobots_loader_and_normaliser_read_it(ds, monkeypatch):
    """LeRobot's `LeRobotDataset` opens the folder offline and its `NormalizerProcessorStep`
    scales every policy feature to finite, standardised values (skipped without the `lerobot`
    package; checked with lerobot 0.4.4, the last release for Python 3.11)."""
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")  # read when huggingface_hub is imported
    pytest.importorskip("lerobot")
    torch = pytest.importorskip("torch")
    try:
        from lerobot.datasets.lerobot_dataset import LeRobotDataset
    except ImportError:
        from lerobot.datasets import LeRobotDataset
    from lerobot.configs.types import FeatureType, NormalizationMode
    from lerobot.datasets.utils import dataset_to_policy_features
    from lerobot.processor.converters import batch_to_transition, transition_to_batch
    from lerobot.processor.normalize_processor import NormalizerProcessorStep

    meta = info(ds)
    dataset = LeRobotDataset("local/sage3d", root=ds)
    assert (dataset.num_episodes, dataset.num_frames) == (meta["total_episodes"], meta["total_frames"])
    item = dataset[0]
    assert item["observation.images.rgb"].shape == (3, H, W)
    assert item["action"].shape == (4,) and item["action"].dtype == torch.float32
    tasks = pd.read_parquet(ds / "meta" / "tasks.parquet")
    assert item["task"] == tasks.index[int(item["task_index"])]
    # An action chunk, as ACT and diffusion policies ask for: [steps, 4], padded past the end.
    chunked = LeRobotDataset("local/sage3d", root=ds, delta_timestamps={"action": [0.0, 1.0, 2.0]})
    assert chunked[0]["action"].shape == (3, 4)

    features = dataset_to_policy_features(dataset.meta.features)
    assert features["action"].type == FeatureType.ACTION and features["action"].shape == (4,)
    batch = next(iter(torch.utils.data.DataLoader(dataset, batch_size=len(dataset))))
    for mode in (NormalizationMode.MEAN_STD, NormalizationMode.MIN_MAX):
        step = NormalizerProcessorStep.from_lerobot_dataset(
            dataset, features, {t: mode for t in (FeatureType.VISUAL, FeatureType.STATE, FeatureType.ACTION)})
        out = transition_to_batch(step(batch_to_transition(dict(batch))))
        for name in ("action", "observation.state", "observation.images.rgb", "observation.depth"):
            v = out[name].double()
            assert torch.isfinite(v).all(), (mode, name)
            if mode == NormalizationMode.MIN_MAX:
                assert v.min() >= -1 - 1e-5 and v.max() <= 1 + 1e-5, name
        if mode == NormalizationMode.MEAN_STD:
            # Every element that varies comes out with mean 0 and std 1 over the dataset.
            a = out["action"].double()
            varies = batch["action"].double().std(dim=0) > 0
            assert (a.mean(dim=0)[varies].abs() < 1e-4).all()
            assert ((a.std(dim=0, unbiased=False)[varies] - 1).abs() < 1e-3).all()
