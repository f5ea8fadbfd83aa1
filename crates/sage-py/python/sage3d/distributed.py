"""Dataset generation, evaluation and training-data rendering spread over a Ray cluster: one
task per scene, results merged deterministically into the files ``sage3d data build``,
``sage3d eval`` and ``sage3d data render`` write.

Scenes and datasets must be readable at the same paths on every node (a shared file system);
the per-scene outputs travel back to the driver, which writes the merged files. Start a
cluster with ``ray start --head`` (then ``ray start --address=HEAD:6379`` on each worker) and
call these functions after ``ray.init(address="auto")``; without a cluster, ``ray.init()``
runs them on this machine.
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
import time

from . import _sage3d
from .evaluation import agent_factory, agent_name, overrides_json


def _ray():
    try:
        import ray
    except ImportError as e:  # pragma: no cover - depends on the installation
        raise ImportError("sage3d.distributed needs Ray: pip install 'sage3d[ray]'") from e
    if not ray.is_initialized():
        ray.init()
    return ray


def _build_scene(scene_dir, out, params):
    return _sage3d.build_scene(scene_dir, out, **params)


def generate(scenes, out, per_scene: int = 20, seed: int = 0, base_actions: int | None = None,
             nogoal: int = 1, high_per_type: int = 1, balanced: int = 1000,
             scene_unseen: float = 0.15, val: float = 0.1, num_cpus: float = 1) -> dict:
    """``sage3d data build SCENES --out OUT ...`` with one Ray task per scene.

    Each task writes (or resumes) ``out/scenes/{scene}.json``; the driver writes any scene file
    it does not see (no shared output folder), then assembles splits, files and summary in scene
    name order, so the dataset is byte-identical to the CLI's. Returns ``{"scenes": [outcome per
    scene], "summary": ...}``.
    """
    ray = _ray()
    out = os.fspath(out)
    dirs = [os.fspath(d) for d in _sage3d.scene_dirs(os.fspath(scenes))]
    params = dict(per_scene=per_scene, seed=seed, base_actions=base_actions, nogoal=nogoal,
                  high_per_type=high_per_type)
    task = ray.remote(num_cpus=num_cpus)(_build_scene)
    results = ray.get([task.remote(d, out, params) for d in dirs])
    for outcome, text in results:
        path = os.path.join(out, "scenes", f"{outcome['scene']}.json")
        if text is not None and not os.path.exists(path):
            os.makedirs(os.path.dirname(path), exist_ok=True)
            tmp = f"{path}.tmp-{os.getpid()}"
            with open(tmp, "w") as f:
                f.write(text)
            os.replace(tmp, path)
    summary = _sage3d.assemble_dataset(out, dirs, balanced=balanced, scene_unseen=scene_unseen,
                                       val=val, **params)
    return {"scenes": [o for o, _ in results], "summary": summary}


def _evaluate_shard(dataset, scenes, agent, shard_out, kwargs, scene):
    _sage3d.evaluate(dataset, scenes, shard_out, agent, scenes_only=[scene], **kwargs)
    with open(os.path.join(shard_out, "episodes.jsonl")) as f:
        return f.read()


def evaluate(dataset, scenes, agent, out, split: str = "test_balanced", mode: str = "sage",
             seed: int = 0, preset: str = "sage", width: int | None = None,
             height: int | None = None, sensors=None, config: dict | None = None,
             num_cpus: float = 1, dtw: str = "exact") -> dict:
    """:func:`sage3d.evaluate` with one Ray task per scene of the split.

    Task ``scene`` runs (or resumes) the run folder ``out/shards/{scene}``; the driver merges
    the shards' records into ``out/episodes.jsonl`` sorted by episode id, with ``summary.json``
    and ``sage3d_run.json`` equal to one ``sage3d eval`` over the whole split. ``agent`` as in
    :func:`sage3d.evaluate` (a Python agent must be picklable). An agent whose server holds one
    episode's state (``socket:HOST:PORT?server=navid``) gets its tasks one after another, as
    ``sage3d eval`` runs its episodes one at a time. Returns the summary.
    """
    ray = _ray()
    dataset, scenes, out = os.fspath(dataset), os.fspath(scenes), os.fspath(out)
    names = sorted({e["scene"] for e in _sage3d.read_split(dataset, split)})
    overrides = overrides_json(width, height, sensors, config)
    spec = _sage3d.agent_spec(agent) if isinstance(agent, str) else None
    name = spec["name"] if spec else agent_name(agent)
    kwargs = dict(agent_name=None if isinstance(agent, str) else name, split=split, mode=mode,
                  seed=seed, preset=preset, overrides=overrides, dtw=dtw)
    factory = agent_factory(agent)
    task = ray.remote(num_cpus=num_cpus)(_evaluate_shard)

    def shard(n):
        return task.remote(dataset, scenes, factory, os.path.join(out, "shards", n), kwargs, n)

    if spec and spec["serial"]:
        shards = [ray.get(shard(n)) for n in names]
    else:
        shards = ray.get([shard(n) for n in names])
    return _sage3d.merge_eval(dataset, scenes, out, name, shards, split=split,
                              mode=mode, seed=seed, preset=preset, dtw=dtw)


def _route_done(out, scene, route):
    """True when ``out`` holds the route's record with a walk (as the render tells a finished
    route: a record without one names an error and is retried)."""
    path = os.path.join(out, "images", scene, route, "route.json")
    try:
        with open(path) as f:
            return "walk" in json.load(f)
    except (OSError, ValueError):
        return False


def _render_training_scene(settings_json, scene, done):
    """One scene of a training-data render, in a temporary folder of this node: the records of
    the routes already done (``done``: relative path -> bytes) are put there first, so only
    the others are rendered. Returns (routes rendered, {relative path: bytes} of the files
    written under ``images/{scene}/``)."""
    with tempfile.TemporaryDirectory(prefix=f"sage3d-train-{scene}-") as tmp:
        for rel, data in done.items():
            path = os.path.join(tmp, rel)
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "wb") as f:
                f.write(data)
        n = _sage3d.training_render_scene(settings_json, scene, tmp)
        files = {}
        root = os.path.join(tmp, "images", scene)
        for dirpath, _, names in os.walk(root):
            for name in names:
                path = os.path.join(dirpath, name)
                rel = os.path.relpath(path, tmp).replace(os.sep, "/")
                if rel not in done:
                    with open(path, "rb") as f:
                        files[rel] = f.read()
        return n, files


def _write_atomic(path, data):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    tmp = f"{path}.tmp-{os.getpid()}"
    with open(tmp, "wb") as f:
        f.write(data)
    os.replace(tmp, path)


def _write_routes(out, files):
    """Writes a scene's returned files into ``out`` route by route: the route's old folder
    removed, its frames, then its ``route.json`` last (the record marks the route done)."""
    routes = {}
    for rel, data in files.items():
        routes.setdefault(rel.rsplit("/", 1)[0], []).append((rel, data))
    for route_dir, entries in sorted(routes.items()):
        shutil.rmtree(os.path.join(out, route_dir), ignore_errors=True)
        entries.sort(key=lambda e: (e[0].endswith("/route.json"), e[0]))
        for rel, data in entries:
            _write_atomic(os.path.join(out, rel), data)


def _progress(total):
    """A progress display: tqdm when installed, else one line per scene on stderr."""
    try:
        from tqdm.auto import tqdm
    except ImportError:
        tqdm = None
    if tqdm is not None:
        bar = tqdm(total=total, unit="scene", desc="training data")

        def step(scene, note):
            bar.set_postfix_str(f"{scene}: {note}")
            bar.update(1)

        return step, bar.close
    state = {"done": 0, "start": time.monotonic()}

    def step(scene, note):
        state["done"] += 1
        print(f"[{state['done']}/{total}] {scene}: {note} "
              f"({time.monotonic() - state['start']:.1f} s)", file=sys.stderr, flush=True)

    return step, lambda: None


def render_training_data(dataset, scenes, out, num_cpus: float = 1, force: bool = False,
                         progress: bool = True, **kwargs) -> dict:
    """:func:`sage3d.render_training_data` with one Ray task per scene.

    ``kwargs`` are those of :func:`sage3d.render_training_data` (``split``, ``preset``,
    ``format``, ``sensors``, ``limit``, …). The driver claims ``out`` (as the command line
    does: a new or empty folder, or the same render's to resume; ``force`` replaces another
    render's output); each task renders its scene into a temporary folder of its node and
    returns the files of ``images/{scene}/``, which the driver writes into ``out`` (each file
    through a temporary name, each route's ``route.json`` last); once every scene is there the
    driver writes the format's files and the manifest. Only the driver writes ``out`` (no
    shared output folder); the dataset and scene folders must be readable at the same paths on
    every node. The output is byte-identical to the single-machine render's. Resumable: routes
    whose records are already in ``out`` are not rendered again, and scenes whose routes are
    all there get no task. ``progress`` prints a line per finished scene (a tqdm bar when tqdm is
    installed). A task that fails, or whose node is lost, raises ``RuntimeError`` naming the
    scene, after the other scenes are written (a rerun renders only what is missing).
    Returns the manifest.
    """
    ray = _ray()
    dataset, scenes, out = os.fspath(dataset), os.fspath(scenes), os.fspath(out)
    settings = _sage3d.training_settings(dataset, scenes, **kwargs)
    finished = _sage3d.training_claim(settings, out, force)
    if finished is not None:
        return finished
    routes = _sage3d.training_plan_routes(settings)
    pending = {}
    for scene, names in routes.items():
        done = {}
        for name in names:
            if _route_done(out, scene, name):
                rel = f"images/{scene}/{name}/route.json"
                with open(os.path.join(out, rel), "rb") as f:
                    done[rel] = f.read()
        if len(done) < len(names):
            pending[scene] = done
    task = ray.remote(num_cpus=num_cpus)(_render_training_scene)
    refs = {task.remote(settings, scene, done): scene for scene, done in pending.items()}
    step, close = _progress(len(refs)) if progress else (lambda *a: None, lambda: None)
    failed = []
    try:
        waiting = list(refs)
        while waiting:
            ready, waiting = ray.wait(waiting, num_returns=1)
            scene = refs[ready[0]]
            try:
                n, files = ray.get(ready[0])
            except ray.exceptions.RayError as e:
                failed.append((scene, e))
                step(scene, f"failed: {type(e).__name__}")
                continue
            _write_routes(out, files)
            frames = sum(1 for rel in files if _frame_rgb(rel))
            errors = sum(1 for rel, data in files.items()
                         if rel.endswith("/route.json") and "error" in json.loads(data))
            step(scene, f"{n} walks, {frames} frames"
                 + (f", {errors} could not be walked" if errors else ""))
    finally:
        close()
    if failed:
        names = ", ".join(s for s, _ in failed)
        scene, err = failed[0]
        raise RuntimeError(
            f"training-data render: {len(failed)} of {len(refs)} scene tasks failed ({names}); "
            f"scene {scene}: {_cause(err)}; the other scenes are written to {out}, run again to "
            "render what is missing") from err
    return _sage3d.training_finish(settings, out)


def _frame_rgb(rel):
    """True for a frame's RGB file (``0003.jpg`` / ``0003.png``, not ``0003.depth.png`` or
    ``route.json``)."""
    name = rel.rsplit("/", 1)[-1]
    return name.count(".") == 1 and name != "route.json"


def _cause(err):
    """The message of a Ray error: the task's own exception when it raised one."""
    cause = getattr(err, "cause", None)
    if isinstance(cause, BaseException):
        return f"{type(cause).__name__}: {cause}"
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[-1] if text else ''}"
