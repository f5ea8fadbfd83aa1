"""Dataset generation and evaluation spread over a Ray cluster: one task per scene, results
merged deterministically into the files ``sage3d data build`` and ``sage3d eval`` write.

Scenes and datasets must be readable at the same paths on every node (a shared file system);
the per-scene outputs travel back to the driver, which writes the merged files. Start a
cluster with ``ray start --head`` (then ``ray start --address=HEAD:6379`` on each worker) and
call these functions after ``ray.init(address="auto")``; without a cluster, ``ray.init()``
runs them on this machine.
"""

from __future__ import annotations

import os

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
