"""Dataset generation, evaluation and training-data rendering spread over a Ray cluster: one
task per scene, results merged deterministically into the files ``sage3d data build``,
``sage3d eval`` and ``sage3d data render`` write.

Scenes and datasets must be readable at the same paths on every node (a shared file system);
the per-scene outputs travel back to the driver, which writes the merged files. Start a
cluster with ``ray start --head`` (then ``ray start --address=HEAD:6379`` on each worker; with
token authentication, the same token and ``RAY_AUTH_MODE=token`` on every node, see
``docs/python.md``) and call these functions after ``ray.init(address="auto")`` on a node of
the cluster; without a cluster, ``ray.init()`` runs them on this machine.

While tasks run, the driver prints progress to stderr (a tqdm bar when tqdm is installed) and a
line when a node of the cluster is lost. A task whose worker or node dies is rerun by Ray (its
``max_retries``); a task that still fails is named with its scene and what was lost, and once
the other tasks are done the call raises ``RuntimeError``: a rerun redoes only what is missing.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile
import time

from . import _args, _sage3d
from .evaluation import agent_factory, agent_name, check_agent, overrides_json


def _ray():
    try:
        import ray
    except ImportError as e:  # pragma: no cover - depends on the installation
        raise ImportError("sage3d.distributed needs Ray: pip install 'sage3d[ray]'") from e
    if not ray.is_initialized():
        ray.init()
    return ray


# Ray's errors for a task that did not fail by itself: what was lost, by class name (looked up
# on ``ray.exceptions``, so a Ray without one of them still works).
_LOST = (
    ("NodeDiedError", "its node was lost"),
    ("LocalRayletDiedError", "its node's raylet died"),
    ("WorkerCrashedError", "its worker process died"),
    ("OutOfMemoryError", "its worker was killed for lack of memory"),
    ("ActorDiedError", "the actor running it died"),
    ("ObjectLostError", "its result was lost with the node holding it"),
)


def _lost(ray, err):
    """What a Ray system failure lost (a node, a worker process, an actor, a result), or
    ``None`` when the task itself raised. A task error wrapping such a failure (a task that
    waited on a lost object) counts as the failure it wraps."""
    for name, what in _LOST:
        cls = getattr(ray.exceptions, name, None)
        if cls is not None and isinstance(err, cls):
            return what
    cause = getattr(err, "cause", None)
    if isinstance(err, ray.exceptions.RayTaskError) and isinstance(cause, BaseException) \
            and cause is not err:
        return _lost(ray, cause)
    return None


def _describe(ray, err):
    """A failed task's error in one line: what was lost, or the task's own exception."""
    what = _lost(ray, err)
    if what is not None:
        return f"{what} ({type(err).__name__})"
    return _cause(err)


class _Tasks:
    """Waits on Ray tasks as they finish (``ray.wait``): progress in ``unit`` up to ``total``,
    a line when a node of the cluster is lost, and each failed task kept with its key."""

    def __init__(self, ray, total, unit, desc, progress=True):
        self.ray = ray
        self.failed = []
        self.step, self.note, self.close = _progress(total, unit, desc, progress)
        self.nodes = self._alive()

    def _alive(self):
        try:
            return {n["NodeID"]: n.get("NodeManagerAddress", "?")
                    for n in self.ray.nodes() if n.get("Alive")}
        except Exception:  # pragma: no cover - a driver without the cluster's state API
            return {}

    def _watch_nodes(self):
        alive = self._alive()
        for node, address in self.nodes.items():
            if node not in alive:
                self.note(f"node {node[:12]} ({address}) was lost; Ray reruns the tasks it held "
                          "(up to their max_retries), which resume what was written")
        self.nodes = alive

    def gather(self, refs, on_result):
        """Waits on ``refs`` (ref -> key); ``on_result(key, value)`` returns ``(units done,
        note)`` for the progress line. A failed task is noted at once and kept in
        ``failed`` as ``(key, error)``."""
        waiting = list(refs)
        while waiting:
            ready, waiting = self.ray.wait(waiting, num_returns=1, timeout=10.0)
            self._watch_nodes()
            for ref in ready:
                key = refs[ref]
                try:
                    value = self.ray.get(ref)
                except self.ray.exceptions.RayError as e:
                    self.failed.append((key, e))
                    self.note(f"{key}: task failed: {_describe(self.ray, e)}")
                    self.step(key, "failed", 0)
                    continue
                done, note = on_result(key, value)
                self.step(key, note, done)

    def raise_failed(self, what, tasks, out):
        """Raises ``RuntimeError`` naming the failed tasks' keys and the first one's error."""
        if not self.failed:
            return
        names = ", ".join(k for k, _ in self.failed)
        key, err = self.failed[0]
        raise RuntimeError(
            f"{what}: {len(self.failed)} of {tasks} scene tasks failed ({names}); scene {key}: "
            f"{_describe(self.ray, err)}; the other scenes are written to {out}, run again to do "
            "what is missing") from err


def _build_scene(scene_dir, out, settings):
    return _sage3d.build_scene(scene_dir, out, **settings)


def generate(scenes, out, num_cpus: float = 1, progress: bool = True, **settings) -> dict:
    """``sage3d data build SCENES --out OUT ...`` with one Ray task per scene.

    ``settings`` are those of :func:`sage3d.build_dataset` (``data build``'s flags by name:
    ``per_scene``, ``seed``, ``agent``, ``length_mix``, ``base_actions``, ``nogoal``,
    ``high_per_type``, ``balanced``, ``scene_unseen``, ``val``, …). Each task writes (or
    resumes) ``out/scenes/{scene}.json``; the driver writes any scene file it does not see (no
    shared output folder), then assembles splits, files and summary in scene name order, so the
    dataset is byte-identical to the CLI's, and its run record names the scenes folder as the
    CLI's does. The driver holds ``out``'s lock from the claim to the assembly, so another
    command writing ``out`` meanwhile (``sage3d data build``, another ``generate``) is refused.
    ``progress`` prints a line per finished scene. Returns ``{"scenes": [outcome per scene],
    "summary": ...}``.
    """
    # Every argument is checked before Ray starts; a misspelt or bad setting fails here, naming
    # it, not in every task.
    scenes = _args.path("generate: scenes", scenes)
    out = _args.path("generate: out", out)
    num_cpus = _args.number("generate: num_cpus", num_cpus)
    progress = _args.flag("generate: progress", progress)
    # The lock is the driver's, from the claim to the assembly: the tasks run in other
    # processes (other nodes) and take none, so no other command may write ``out`` meanwhile.
    with _sage3d.dataset_claim(out, **settings) as claim:
        ray = _ray()
        dirs = [os.fspath(d) for d in _sage3d.scene_dirs(scenes)]
        outcomes = _build_claimed(ray, dirs, out, num_cpus, progress, settings)
        summary = _sage3d.assemble_dataset(out, dirs, scenes, claim=claim, **settings)
    return {"scenes": [outcomes[os.path.basename(d)] for d in dirs], "summary": summary}


def _build_claimed(ray, dirs, out, num_cpus, progress, settings):
    """The scenes of a claimed dataset build, one Ray task each, their files written into
    ``out`` as the tasks finish where a task's node does not share it; returns each scene's
    outcome by name, or raises ``RuntimeError`` naming the scenes whose task failed, once the
    others are written."""
    task = ray.remote(num_cpus=num_cpus)(_build_scene)
    refs = {task.remote(d, out, settings): os.path.basename(d) for d in dirs}
    outcomes = {}

    def written(scene, result):
        outcome, file, text = result
        path = os.path.join(out, file)
        if text is not None and not os.path.exists(path):
            os.makedirs(os.path.dirname(path), exist_ok=True)
            tmp = _temp_path(path)
            with open(tmp, "w") as f:
                f.write(text)
            os.replace(tmp, path)
        outcomes[scene] = outcome
        return 1, f"{outcome['status']}, {outcome['episodes']} episodes"

    tasks = _Tasks(ray, len(refs), "scenes", "dataset", progress)
    try:
        tasks.gather(refs, written)
    finally:
        tasks.close()
    tasks.raise_failed("dataset generation", len(refs), out)
    return outcomes


def _evaluate_shard(dataset, scenes, agent, shard_out, kwargs, scene):
    _sage3d.evaluate(dataset, scenes, shard_out, agent, scenes_only=[scene], report=False,
                     **kwargs)
    return _sage3d.run_records(shard_out)


def evaluate(dataset, scenes=None, agent=None, out=None, width: int | None = None,
             height: int | None = None, sensors=None, config: dict | None = None,
             num_cpus: float = 1, max_retries: int = 3, progress: bool = True,
             **options) -> dict:
    """:func:`sage3d.evaluate` with one Ray task per scene of the split.

    ``scenes=None`` uses the scenes folder the dataset records (resolved once, on the driver).
    Task ``scene`` runs (or resumes) the run folder ``out/shards/{scene}``; the driver merges
    the shards' records into ``out/episodes.jsonl`` sorted by episode id, with
    ``episodes.jsonl``, ``summary.json`` and ``sage3d_run.json`` the same bytes as one ``sage3d
    eval`` over the whole split, then writes the run's report (``report.html``). ``agent`` and
    ``options`` (``split``, ``mode``, ``dtw``, ``seed``, ``preset``, ``device``: every task
    renders on it; ``splat_bodies``) as in :func:`sage3d.evaluate` (a Python agent must be picklable). An agent
    whose server holds one episode's state (``socket:HOST:PORT?server=navid``) gets its tasks
    one after another, as ``sage3d eval`` runs its episodes one at a time. ``progress`` prints the episodes done (of the split) as
    tasks finish. A task whose worker or node dies is rerun up to ``max_retries`` times (Ray's
    task option; the rerun resumes its shard); a task that still fails is reported with its
    scene, and once the others are done ``RuntimeError`` is raised, nothing merged: a rerun
    runs only the missing episodes. Returns the summary.
    """
    if agent is None or out is None:
        raise TypeError("evaluate() needs agent and out")
    # Every argument is checked before Ray starts.
    check_agent("distributed.evaluate: agent", agent)
    dataset = _args.path("distributed.evaluate: dataset", dataset)
    given_scenes = _args.optional_path("distributed.evaluate: scenes", scenes)
    out = _args.path("distributed.evaluate: out", out)
    num_cpus = _args.number("distributed.evaluate: num_cpus", num_cpus)
    max_retries = _args.whole("distributed.evaluate: max_retries", max_retries)
    progress = _args.flag("distributed.evaluate: progress", progress)
    overrides = overrides_json(width, height, sensors, config)
    split = _sage3d.evaluation_options(**options)["split"]
    ray = _ray()
    scenes = os.fspath(_sage3d.scenes_folder(dataset, given_scenes))
    episodes = _sage3d.read_split(dataset, split)
    names = sorted({e["scene"] for e in episodes})
    spec = _sage3d.agent_spec(agent) if isinstance(agent, str) else None
    name = spec["name"] if spec else agent_name(agent)
    kwargs = dict(options, agent_name=None if isinstance(agent, str) else name,
                  overrides=overrides)
    factory = agent_factory(agent)
    task = ray.remote(num_cpus=num_cpus, max_retries=max_retries)(_evaluate_shard)
    texts = {}

    def shard(n):
        return {task.remote(dataset, scenes, factory, os.path.join(out, "shards", n), kwargs, n): n}

    def merged(scene, text):
        texts[scene] = text
        n = sum(1 for line in text.splitlines() if line.strip())
        return n, f"{n} episodes"

    tasks = _Tasks(ray, len(episodes), "episodes", "evaluation", progress)
    try:
        if spec and spec["serial"]:
            for n in names:
                tasks.gather(shard(n), merged)
        else:
            refs = {}
            for n in names:
                refs.update(shard(n))
            tasks.gather(refs, merged)
    finally:
        tasks.close()
    tasks.raise_failed("distributed evaluation", len(names), os.path.join(out, "shards"))
    return _sage3d.merge_eval(dataset, scenes, out, name, [texts[n] for n in names],
                              overrides=overrides, python_agent=not isinstance(agent, str),
                              **options)


def _render_training_scene(settings_json, scene, done):
    """One scene of a training-data render, in a temporary folder of this node: the records of
    the routes already done (``done``: relative path -> bytes) are put there first, so only
    the others are rendered. Returns (what the render says it did, {relative path: bytes} of
    the files it wrote, in the order to write them)."""
    with tempfile.TemporaryDirectory(prefix=f"sage3d-train-{scene}-") as tmp:
        for rel, data in done.items():
            path = os.path.join(tmp, rel)
            os.makedirs(os.path.dirname(path), exist_ok=True)
            with open(path, "wb") as f:
                f.write(data)
        result = _sage3d.training_render_scene(settings_json, scene, tmp)
        files = {}
        for rel in result["files"]:
            with open(os.path.join(tmp, rel), "rb") as f:
                files[rel] = f.read()
        return result, files


def _temp_path(path):
    """A temporary sibling of ``path`` named as the library names its own
    (``.{name}.tmp-{pid}-{n}``), so that a rerun recognises one an interrupted write left and
    removes it."""
    head, name = os.path.split(path)
    return os.path.join(head, f".{name}.tmp-{os.getpid()}-0")


def _write_atomic(path, data):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    tmp = _temp_path(path)
    with open(tmp, "wb") as f:
        f.write(data)
    os.replace(tmp, path)


def _write_routes(out, files):
    """Writes a scene's returned files into ``out`` route by route, in the order the render
    listed them (each route's record last: the record marks the route done), each route's old
    folder removed first."""
    routes = {}
    for rel, data in files.items():
        routes.setdefault(rel.rsplit("/", 1)[0], []).append((rel, data))
    for route_dir, entries in sorted(routes.items()):
        shutil.rmtree(os.path.join(out, route_dir), ignore_errors=True)
        for rel, data in entries:
            _write_atomic(os.path.join(out, rel), data)


def _progress(total, unit, desc, show=True):
    """A progress display of ``total`` ``unit``: tqdm when installed, else one line per finished
    task on stderr. Returns ``(step(key, note, done), note(text), close())``; ``note`` prints a
    line whether or not progress is shown."""
    try:
        # tqdm is optional and ships no type hints (types-tqdm has them).
        from tqdm.auto import tqdm  # type: ignore[import-untyped, import-not-found, unused-ignore]
    except ImportError:
        tqdm = None
    if show and tqdm is not None:
        bar = tqdm(total=total, unit=unit.rstrip("s"), desc=desc)

        def step(key, note, done):
            bar.set_postfix_str(f"{key}: {note}")
            bar.update(done)

        return step, lambda text: bar.write(text, file=sys.stderr), bar.close
    state = {"done": 0, "start": time.monotonic()}

    def note(text):
        print(text, file=sys.stderr, flush=True)

    def step(key, text, done):
        state["done"] += done
        if show:
            note(f"[{state['done']}/{total} {unit}] {key}: {text} "
                 f"({time.monotonic() - state['start']:.1f} s)")

    return step, note, lambda: None


def render_training_data(dataset, scenes, out, num_cpus: float = 1, force: bool = False,
                         progress: bool = True, **kwargs) -> dict:
    """:func:`sage3d.render_training_data` with one Ray task per scene.

    ``scenes=None`` uses the scenes folder the dataset records. ``kwargs`` are those of
    :func:`sage3d.render_training_data` (``split``, ``preset``,
    ``format``, ``sensors``, ``limit``, …). The driver claims ``out`` (as the command line
    does: a new or empty folder, or the same render's to resume; ``force`` replaces another
    render's output) and holds its lock (``out/.sage3d.lock``) until the call returns, so a
    ``sage3d data render`` or another call on the same folder meanwhile is refused, naming
    this one; each task renders its scene into a temporary folder of its node and
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
    # Every argument is checked before Ray starts.
    dataset = _args.path("distributed.render_training_data: dataset", dataset)
    scenes = _args.optional_path("distributed.render_training_data: scenes", scenes)
    out = _args.path("distributed.render_training_data: out", out)
    num_cpus = _args.number("distributed.render_training_data: num_cpus", num_cpus)
    force = _args.flag("distributed.render_training_data: force", force)
    progress = _args.flag("distributed.render_training_data: progress", progress)
    settings = _sage3d.training_settings(dataset, scenes, **kwargs)
    ray = _ray()
    # The lock is the driver's, for the whole call: the tasks run in other processes (other
    # nodes) and write no file of ``out``, the driver writes every one under it.
    with _sage3d.training_claim(settings, out, force) as claim:
        if claim.manifest is not None:
            return claim.manifest
        _render_claimed(ray, settings, out, num_cpus, progress)
        return _sage3d.training_finish(settings, out, claim)


def _render_claimed(ray, settings, out, num_cpus, progress):
    """The scenes of a claimed render not yet done in ``out``, one Ray task each, their files
    written into ``out`` as the tasks finish; raises ``RuntimeError`` naming the scenes whose
    task failed, once the others are written."""
    pending = {}
    for scene, state in _sage3d.training_progress(settings, out).items():
        if len(state["done"]) < state["routes"]:
            done = {}
            for rel in state["done"]:
                with open(os.path.join(out, rel), "rb") as f:
                    done[rel] = f.read()
            pending[scene] = done
    task = ray.remote(num_cpus=num_cpus)(_render_training_scene)
    refs = {task.remote(settings, scene, done): scene for scene, done in pending.items()}

    def written(scene, result):
        did, files = result
        _write_routes(out, files)
        errors = did["errors"]
        return 1, (f"{did['routes']} walks, {did['frames']} frames"
                   + (f", {errors} could not be walked" if errors else ""))

    tasks = _Tasks(ray, len(refs), "scenes", "training data", progress)
    try:
        tasks.gather(refs, written)
    finally:
        tasks.close()
    tasks.raise_failed("training-data render", len(refs), out)


def _cause(err):
    """The message of a Ray error: the task's own exception when it raised one."""
    cause = getattr(err, "cause", None)
    if isinstance(cause, BaseException):
        return f"{type(cause).__name__}: {cause}"
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[-1] if text else ''}"
