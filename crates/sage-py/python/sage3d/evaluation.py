"""The evaluator of ``sage3d eval`` from Python, with built-in or Python agents."""

from __future__ import annotations

import copy
import warnings

from . import _args, _sage3d
from .env import _json, config_overrides


def agent_name(agent) -> str:
    """The name an agent is recorded under: a built-in name itself, else the agent's ``name``
    attribute, else its class name."""
    if isinstance(agent, str):
        return agent
    name = getattr(agent, "name", None)
    if isinstance(name, str) and name:
        return name
    return agent.__name__ if isinstance(agent, type) else type(agent).__name__


def check_agent(what: str, agent) -> None:
    """Refuses what is no agent at all (``agent=123``) before any episode runs, naming ``what``
    (the argument)."""
    if not (isinstance(agent, str) or callable(agent) or callable(getattr(agent, "act", None))):
        raise TypeError(f"{what}: expected an agent string, a class, or an object with act(obs), "
                        f"got {_args.got(agent)}")


def agent_factory(agent):
    """What the evaluator calls once per episode for a fresh agent: a class (or any callable
    without ``act``) is called; an agent object is deep-copied, so episodes running in
    parallel never share its state."""
    if isinstance(agent, str):
        return agent
    if isinstance(agent, type) or not hasattr(agent, "act"):
        return agent
    return _Copies(agent)


class _Copies:
    """A picklable factory of deep copies of one agent object (Ray ships it to workers)."""

    def __init__(self, agent):
        self.agent = agent

    def __call__(self):
        return copy.deepcopy(self.agent)


def overrides_json(width=None, height=None, sensors=None, config=None) -> str | None:
    """The environment settings a run asks for over its preset, as JSON; ``None`` when it asks
    for none (then built-in agents run blind, as in ``sage3d eval``)."""
    if all(v is None for v in (width, height, sensors, config)):
        return None
    over = config_overrides(width, height, sensors, config=config)
    if "splat_bodies" in over:
        # The run record keeps the bodies as one of the run's settings, as `sage3d eval
        # --splat-bodies` does: evaluate takes them as its own option, not in `config`.
        raise ValueError("config: splat_bodies: give the bodies as evaluate's own option "
                         f"(splat_bodies={over['splat_bodies']!r}), which the run record keeps")
    return _json(over)


def evaluate(dataset, scenes=None, agent=None, out=None, width: int | None = None,
             height: int | None = None, sensors=None, config: dict | None = None,
             scenes_only: list[str] | None = None, strict: bool = False, force: bool = False,
             **options) -> dict:
    """Runs (or resumes) an evaluation into the run folder ``out`` and returns ``{total,
    resumed, ran, summary, table, scene_changes}``; the folder holds ``episodes.jsonl``, ``summary.json``,
    ``sage3d_run.json`` and the report (``report.html`` with its ``report/`` maps) as ``sage3d
    eval`` writes them. ``scenes=None`` uses the scenes folder
    the dataset records (as ``sage3d eval`` without ``--scenes``); ``agent`` and ``out`` are
    required.

    ``agent`` is an agent string as ``sage3d eval --agent`` takes it (``"oracle"``,
    ``"socket:HOST:PORT?server=navila"``, ``"ws:HOST:PORT?state=1"``, …; then exactly the CLI's run), or a Python agent: an object (or class) with ``act(obs) -> action`` and optionally
    ``reset(episode)``; it sees the observations of :class:`~sage3d.SageEnv` (the preset's
    images, resized by ``width``/``height``) and answers actions as ``SageEnv.step`` takes them.
    Each episode gets a fresh agent (the class called, or a deep copy of the object). Episodes
    run in parallel; Python agents decide one at a time under the GIL while rendering and
    physics run in parallel. ``scenes_only`` runs only the episodes of those scenes (a shard).
    ``options`` are ``sage3d eval``'s flags by name, with the same defaults: ``split``
    (``"test_balanced"``), ``mode`` (``"sage"``, ``"vlnce"``, ``"sage-official"`` or ``"gnbench"``) and ``dtw``
    (``"exact"`` or ``"fast"``, VLN-CE's FastDTW) choose how episodes are scored, ``seed`` (0),
    ``preset`` (``"sage"``) and ``device``. Faulted episodes (never scored) are recorded and listed in
    ``summary["failed"]`` (per kind in ``summary["failures"]``); with ``strict=True`` any failure
    raises ``ValueError`` after the run folder is written, as ``sage3d eval --strict`` exits
    non-zero, and a run in which every episode failed warns (``RuntimeWarning``). ``device``
    (``"cpu"``, ``"gpu"`` or ``"auto"``, as ``sage3d eval --device``) is where the images of
    agents that read them are rendered, whatever ``config`` says; ``splat_bodies``
    (``"auto"``, ``"always"`` or ``"never"``, as ``sage3d eval --splat-bodies``) which objects'
    collision bodies are recovered from their Gaussians. ``force=True`` writes into a folder
    of other files, never replacing one (as ``sage3d eval --force``). ``scene_changes`` lists the files
    navigation reads that changed since ``data build`` built the dataset (``"home/labels.json
    changed"``, ``added`` or ``removed``), with a ``RuntimeWarning``: the episodes' goals and
    reference paths were planned on those files as they were.
    """
    if agent is None or out is None:
        raise TypeError("evaluate() needs agent and out")
    check_agent("evaluate: agent", agent)
    dataset = _args.path("evaluate: dataset", dataset)
    scenes = _args.optional_path("evaluate: scenes", scenes)
    out = _args.path("evaluate: out", out)
    if scenes_only is not None:
        scenes_only = _args.sequence("evaluate: scenes_only", scenes_only, "of scene names")
        for name in scenes_only:
            if not isinstance(name, str):
                raise TypeError(f"evaluate: scenes_only: expected a list of scene names, got a list holding "
                                f"{_args.got(name)}")
    strict = _args.flag("evaluate: strict", strict)
    force = _args.flag("evaluate: force", force)
    overrides = overrides_json(width, height, sensors, config)
    result = _sage3d.evaluate(
        dataset, scenes, out, agent_factory(agent),
        agent_name=None if isinstance(agent, str) else agent_name(agent), overrides=overrides,
        scenes_only=scenes_only, strict=strict, force=force, **options)
    if result["scene_changes"]:
        warnings.warn(f"scene files changed since the dataset was built ({', '.join(result['scene_changes'])}): "
                      "its goals and reference paths were planned on the files as they were; build the "
                      "dataset again to score against the scenes as they are", RuntimeWarning, stacklevel=2)
    summary = result["summary"]
    if summary["episodes"] and len(summary["failed"]) == summary["episodes"]:
        warnings.warn(f"every episode of the run faulted ({summary['episodes']}); see the records' "
                      f"\"error\" fields in {out}/episodes.jsonl", RuntimeWarning, stacklevel=2)
    return result
