"""The Gymnasium environment over sage3d scenes (``SageVLN-v0``, ``SageNoGoal-v0``).

Episodes come from a dataset folder (``dataset=``, ``scenes=``), from one scene folder or
:class:`~sage3d.Scene` (episodes made as ``sage3d data build`` makes them), or, with neither, from
a small synthetic home generated once and cached under :func:`cache_dir`.
"""

from __future__ import annotations

import json
import math
import os
import string
import tempfile
from collections.abc import Iterable
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from . import _args, _sage3d
from ._args import whole
from .dataset import Dataset, check_filters, filter_episodes

#: The renderer's far plane (metres): the largest depth an image holds (0 where nothing is hit).
DEPTH_FAR = 100.0
#: Image sensors in observation order.
SENSORS = ("rgb", "depth", "semantic", "instance")
#: Seconds a ground or UAV velocity action may last at most (``actions.max_dt``).
MAX_DT = 1.0
#: Where images can be rendered: the CPU renderer; the GPU renderer on any adapter (a software
#: one included; an error when there is none); a hardware GPU when there is one, else the CPU.
DEVICES = ("cpu", "gpu", "auto")


def check_device(device: str) -> str:
    """``device`` when it is one of :data:`DEVICES`, else ``ValueError``."""
    if device not in DEVICES:
        raise ValueError(f"device: unknown device {device!r} (expected one of {', '.join(DEVICES)})")
    return device


def sensor_names(sensors: str | Iterable[str]) -> list[str]:
    """The sensor names of ``sensors``: ``"rgb,depth"`` as ``data render`` takes it (spaces
    around a name allowed, empty names dropped, as the command line reads it) or a list of
    names; ``ValueError`` naming any that is not one of :data:`SENSORS`."""
    if isinstance(sensors, str):
        sensors = sensors.split(",")
    sensors = _args.sequence("sensors", sensors, 'of sensor names, or "rgb,depth"')
    names = [str(n).strip() for n in sensors]
    names = [n for n in names if n]
    unknown = sorted(set(names) - set(SENSORS))
    if unknown:
        raise ValueError(f"unknown sensors {unknown} (expected some of {list(SENSORS)})")
    return names


def check_options(options: Any, known: tuple[str, ...]) -> dict:
    """The ``options`` of ``reset`` as a dict (``None``: none), after checking that every key
    is one of ``known``: a misspelt key would otherwise be ignored and the episode drawn at
    random instead of the one asked for."""
    if options is None:
        return {}
    if not isinstance(options, dict):
        raise TypeError(f"reset options: expected a dict, got {type(options).__name__}")
    unknown = sorted(str(k) for k in options if k not in known)
    if unknown:
        raise ValueError(f"unknown reset option {', '.join(map(repr, unknown))} "
                         f"(accepted: {', '.join(known)})")
    return options


def cache_dir() -> str:
    """Where synthetic scenes and their collision hulls are cached: ``$SAGE3D_CACHE``, else
    ``sage3d-cache`` in the system's temporary folder."""
    return os.environ.get("SAGE3D_CACHE") or os.path.join(tempfile.gettempdir(), "sage3d-cache")


def synth_scene(seed: int = 0, kind: str = "home", rooms: int = 4, objects: int = 40,
                gaussians: int = 60_000, cache: str | None = None) -> _sage3d.Scene:
    """A synthetic scene, generated on first use and then loaded from the cache (keyed by
    kind, seed and sizes; collision hulls are cached beside it)."""
    cache = _args.optional_path("cache", cache)
    root = os.path.join(cache or cache_dir(), "synth")
    return _sage3d.Scene.synth(root, seed=whole("seed", seed), kind=_args.text("kind", kind),
                               rooms=whole("rooms", rooms, 1), objects=whole("objects", objects),
                               gaussians=whole("gaussians", gaussians, 1))


def _merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for k, v in over.items():
        out[k] = _merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def config_overrides(width: int | None = None, height: int | None = None,
                     sensors: str | Iterable[str] | None = None, actions: str = "discrete",
                     max_steps: int | None = None, hfov: float | None = None,
                     config: dict | None = None, device: str | None = None) -> dict:
    """The environment settings over the preset (``EnvConfig`` fields, as JSON) from the
    keyword arguments of :class:`SageEnv`; ``config`` is merged last, key by key."""
    o: dict = {}
    if device is not None:
        o["device"] = check_device(device)
    s: dict = {}
    if width is not None:
        s["width"] = whole("width", width, 1)
    if height is not None:
        s["height"] = whole("height", height, 1)
    if hfov is not None:
        s["hfov_deg"] = _args.number("hfov", hfov)
    if sensors is not None:
        names = sensor_names(sensors)
        s.update({k: k in names for k in SENSORS})
    if s:
        o["sensors"] = s
    if actions == "ground":
        o["actions"] = {"kind": "ground", "max_dt": MAX_DT}
    elif actions == "uav":
        o["actions"] = {"kind": "uav", "max_dt": MAX_DT}
        o["agent"] = "uav"
    elif actions != "discrete":
        raise ValueError(f"actions: unknown action space {actions!r} (expected discrete, ground or uav)")
    if max_steps is not None:
        o["task"] = {"max_steps": whole("max_steps", max_steps, 1)}
    config = {} if config is None else _args.mapping("config", config, "of EnvConfig fields")
    return _merge(o, config)


def episode_pool(scene=None, dataset=None, scenes=None, split: str = "train", episodes=None,
                 task: str | None = None, filters: dict | None = None, num_episodes: int = 8,
                 seed: int = 0, synth: dict | None = None, splat_bodies: str = "auto"):
    """The scenes and episodes an environment draws from: ``(scenes, episodes, scene_of)``,
    episode ``i`` running in ``scenes[scene_of[i]]``. Scene folders are loaded with
    ``splat_bodies`` (the config's choice of bodies recovered from Gaussians); a
    :class:`sage3d.Scene` given must have been loaded with it."""
    filters = {} if filters is None else _args.mapping("filters", filters, "of episode filters")
    if task is not None:
        filters["task"] = task
    # Every argument is checked before a scene is loaded or synthesised.
    check_filters(filters)
    split = _args.text("split", split)
    dataset = _args.optional_path("dataset", dataset)
    scenes = _args.optional_path("scenes", scenes)
    seed = whole("seed", seed)
    synth = {} if synth is None else _args.mapping("synth", synth, "of synth_scene's arguments")
    if scene is not None and not isinstance(scene, _sage3d.Scene):
        if not isinstance(scene, (str, os.PathLike)):
            raise TypeError(f"scene: expected a sage3d.Scene or a scene folder (str or os.PathLike), "
                            f"got {_args.got(scene)}")
        scene = _args.path("scene", scene)
    if dataset is not None:
        if scenes is None:
            raise ValueError("dataset= needs scenes= (the scene folder, or the folder of scene folders)")
        eps = Dataset(dataset).episodes(split, **filters)
        dirs = {os.path.basename(d): d for d in _sage3d.scene_dirs(scenes)}
        names = sorted({e["scene"] for e in eps})
        missing = [n for n in names if n not in dirs]
        if missing:
            raise ValueError(f"scenes {missing} of the dataset are not in {scenes!r}")
        loaded = [_sage3d.Scene.load(dirs[n], splat_bodies=splat_bodies) for n in names]
        index = {n: i for i, n in enumerate(names)}
        scene_of = [index[e["scene"]] for e in eps]
    else:
        if scene is None:
            scene = synth_scene(**synth)
            if splat_bodies != "auto":
                scene = _sage3d.Scene.load(scene.path, splat_bodies=splat_bodies)
        elif not isinstance(scene, _sage3d.Scene):
            scene = _sage3d.Scene.load(scene, splat_bodies=splat_bodies)
        if scene.splat_bodies != splat_bodies:
            # Its bodies were built as it was loaded: the config cannot change them.
            raise ValueError(f"splat_bodies: the config asks for {splat_bodies!r} but scene "
                             f"{scene.name!r} was loaded with {scene.splat_bodies!r}; load it "
                             f"with Scene.load(..., splat_bodies={splat_bodies!r})")
        eps = episodes if episodes is not None else scene.episodes(
            count=whole("num_episodes", num_episodes, 1), seed=seed)
        eps = filter_episodes(eps, **filters)
        loaded, scene_of = [scene], [0] * len(eps)
    if not eps:
        raise ValueError(f"no episodes match (split {split!r}, filters {filters})")
    return loaded, eps, scene_of


def observation_space(config: dict, instructions: Iterable[str]) -> spaces.Dict:
    """The Dict observation space of a resolved config (:func:`sage3d.env_config`): the
    configured images as Box, ``pose`` ``[x, y, z, yaw]`` and the ``instruction`` as Text."""
    s = config["sensors"]
    h, w = s["height"], s["width"]
    dw, dh = s.get("depth_size") or (w, h)
    d: dict[str, spaces.Space[Any]] = {}
    if s["rgb"]:
        d["rgb"] = spaces.Box(0, 255, (h, w, 3), np.uint8)
    if s["depth"]:
        d["depth"] = spaces.Box(0.0, DEPTH_FAR, (dh, dw), np.float32)
    if s["semantic"]:
        d["semantic"] = spaces.Box(0, np.iinfo(np.uint16).max, (h, w), np.uint16)
    if s["instance"]:
        d["instance"] = spaces.Box(0, np.iinfo(np.uint32).max, (h, w), np.uint32)
    d["pose"] = spaces.Box(-np.inf, np.inf, (4,), np.float32)
    texts = list(instructions)
    charset = frozenset(string.printable).union(*texts)
    d["instruction"] = spaces.Text(max([1024, *map(len, texts)]), min_length=0, charset=charset)
    return spaces.Dict(d)


def check_discrete(space: spaces.Space, action: Any, name: str = "action") -> None:
    """Refuses an index outside a discrete action space: the simulator takes every index of
    the six actions, but an env made without ``look`` offers four, and LOOK_UP / LOOK_DOWN
    must not pass as if offered. (Velocities outside a Box are clamped to the agent's limits by
    the physics, as documented.) ``name`` is the argument the message names."""
    if isinstance(space, spaces.MultiDiscrete):
        indices = np.asarray(action)
        # Not one index per sub-environment: the simulator's message says what it wants.
        if indices.shape != space.shape:
            return
        inside = np.issubdtype(indices.dtype, np.integer) and space.contains(indices.astype(np.int64))
    elif isinstance(space, spaces.Discrete):
        inside = space.contains(action)
    else:
        return
    if not inside:
        raise ValueError(f"{name}: {action!r} is not in the action space {space}")


def action_space(config: dict, look: bool = False) -> spaces.Space:
    """Discrete(4) (STOP, FORWARD, LEFT, RIGHT) or Discrete(6) with LOOK_UP / LOOK_DOWN;
    for velocities a Box ``[stop, vx, vy, wz, dt]`` (UAV: ``[stop, vx, vy, vz, wz, dt]``),
    ``stop >= 0.5`` calling STOP, within the agent profile's limits: ``vx`` and ``vy`` each
    within its speed (the physics scales the pair down to it), ``vz`` within its climb rate."""
    a = config["actions"]
    if a["kind"] == "discrete":
        return spaces.Discrete(6 if look else 4)
    p = config["profile"]
    v, wz, dt = p["max_speed"], p["max_yaw_rate"], a["max_dt"]
    if a["kind"] == "ground":
        low, high = [0, -v, -v, -wz, 0], [1, v, v, wz, dt]
    else:
        vz = p["max_climb"]
        low, high = [0, -v, -v, -vz, -wz, 0], [1, v, v, vz, wz, dt]
    return spaces.Box(np.array(low, np.float32), np.array(high, np.float32), dtype=np.float32)


class _Prepared:
    """What the single and the vector environment do first with their keyword arguments."""

    def _prepare(self, render_mode, scene, dataset, scenes, split, episodes, task, filters,
                 num_episodes, seed, synth, preset, width, height, sensors, actions, look,
                 max_steps, hfov, config, mode, device):
        """Checks ``render_mode``, ``look`` and ``mode``, resolves the configuration into
        ``self.config`` and gathers the episode pool into ``self.scenes``; returns (overrides
        JSON, scenes, episodes, scene of each episode)."""
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode: expected None or one of {self.metadata['render_modes']}, "
                             f"got {render_mode!r}")
        _args.flag("look", look)
        _args.text("mode", mode)
        self.render_mode = render_mode
        if render_mode == "rgb_array" and sensors is not None:
            # Names, not text: "depth" as a string would otherwise be spread into letters.
            sensors = sensor_names(sensors)
            if "rgb" not in sensors:
                sensors = [*sensors, "rgb"]
        overrides = _json(config_overrides(width, height, sensors, actions, max_steps, hfov, config,
                                           device))
        self.config = _sage3d.env_config(preset, overrides)
        if render_mode == "rgb_array" and not self.config["sensors"]["rgb"]:
            raise ValueError("render_mode='rgb_array' renders the rgb sensor, which config turns off")
        pool_scenes, eps, scene_of = episode_pool(scene, dataset, scenes, split, episodes, task,
                                                  filters, num_episodes, seed, synth,
                                                  self.config.get("splat_bodies", "auto"))
        self.scenes = pool_scenes
        return overrides, pool_scenes, eps, scene_of


class SageEnv(_Prepared, gym.Env):
    """A sage3d environment as a Gymnasium 1.x ``Env``.

    ``reset(seed=, options=)`` picks an episode with the env's seeded generator, or the one named
    by ``options={"episode_id": ...}`` / ``{"episode_index": i}`` (any other key is a
    ``ValueError``); ``step(action)`` returns
    ``(obs, reward, terminated, truncated, info)``. Observations are NumPy arrays that own the
    rendered buffers. ``info`` holds the episode, pose, contacts, the step record, metrics so far
    and, once the episode has ended, its metrics (mode ``mode``). The environment does not reset
    itself; the vector form does (next-step autoreset).

    ``device`` chooses where images are rendered: ``"cpu"`` (the default), ``"gpu"`` (any GPU
    adapter, a software one included; ``ValueError`` when there is none) or ``"auto"`` (a
    hardware GPU when there is one, else the CPU); :attr:`render_device` says which renderer
    took the work.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4}

    def __init__(self, render_mode: str | None = None, *, scene=None, dataset=None, scenes=None,
                 split: str = "train", episodes=None, task: str | None = None,
                 filters: dict | None = None, num_episodes: int = 8, seed: int = 0,
                 synth: dict | None = None, preset: str = "sage", width: int | None = None,
                 height: int | None = None, sensors: Iterable[str] | None = None,
                 actions: str = "discrete", look: bool = False, max_steps: int | None = None,
                 hfov: float | None = None, config: dict | None = None, mode: str = "sage",
                 device: str = "cpu"):
        overrides, pool_scenes, eps, scene_of = self._prepare(
            render_mode, scene, dataset, scenes, split, episodes, task, filters, num_episodes,
            seed, synth, preset, width, height, sensors, actions, look, max_steps, hfov, config,
            mode, device)
        self._sim = _sage3d.Sim(pool_scenes, _json(eps), scene_of, preset, overrides, mode)
        self._ids = {e["episode_id"]: i for i, e in enumerate(eps)}
        self.observation_space = observation_space(self.config, (e["instruction"] for e in eps))
        self.action_space = action_space(self.config, look)
        self._last: dict[str, Any] | None = None

    @property
    def episodes(self) -> list[dict]:
        """The episodes this environment draws from (dataset schema)."""
        return self._open_sim().episodes()

    @property
    def render_device(self) -> str | None:
        """Which renderer forms the images, in words: ``cpu (8 threads)``, ``gpu: NVIDIA H100
        (Vulkan, discrete)``, or the CPU with the reason ``device="auto"`` took no GPU;
        ``None`` when no image is configured."""
        return self._open_sim().render_device

    #: The keys ``reset(options=...)`` accepts; any other is a ``ValueError``.
    RESET_OPTIONS = ("episode_id", "episode_index")

    def _named(self, options: dict) -> int | None:
        """The episode ``options`` names, or ``None`` where it names none (drawn at random)."""
        if "episode_id" in options:
            try:
                return self._ids[options["episode_id"]]
            except KeyError:
                raise ValueError(f"episode {options['episode_id']!r} is not among this env's episodes") from None
        if "episode_index" in options:
            index = whole("episode_index", options["episode_index"])
            if index >= len(self._ids):
                raise ValueError(f"episode_index: {index} is past this env's {len(self._ids)} episodes")
            return index
        return None

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        # Everything is checked before the generator is reseeded, so a refused call changes nothing.
        options = check_options(options, self.RESET_OPTIONS)
        if "episode_id" in options and "episode_index" in options:
            raise ValueError("reset options: name the episode by episode_id or by episode_index, not both")
        sim = self._open_sim()
        seed = None if seed is None else whole("seed", seed)
        index = self._named(options)
        super().reset(seed=seed)
        if index is None:
            index = int(self.np_random.integers(len(self._ids)))
        obs, info = sim.reset(index)
        self._last = obs
        return obs, info

    def step(self, action):
        sim = self._open_sim()
        check_discrete(self.action_space, action)
        obs, reward, terminated, truncated, info = sim.step(action)
        self._last = obs
        return obs, float(reward), terminated, truncated, info

    def close(self):
        """Frees the scenes, physics and renderer the environment holds; a closed environment
        is not reset or stepped again (``gymnasium.error.ClosedEnvironmentError``), as a
        closed vector environment is not. Closing twice is harmless."""
        self._sim = None
        self._last = None
        super().close()

    def _open_sim(self):
        if self._sim is None:
            raise gym.error.ClosedEnvironmentError("the environment is closed")
        return self._sim

    def render(self):
        """The last RGB observation (``render_mode="rgb_array"``), an ``(H, W, 3)`` uint8 array."""
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; make the env with render_mode='rgb_array'")
            return None
        return None if self._last is None else self._last["rgb"]


def _json(value) -> str:
    """``value`` as JSON for the Rust side, refusing a NaN or infinite number with its place
    (``sensors.hfov_deg``): JSON has none, and the parser would only say it expected a value."""
    _check_finite(value, "")
    return json.dumps(value)


def _check_finite(value, at: str) -> None:
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"`{at}`: expected a finite number, got {value}")
    if isinstance(value, dict):
        for k, v in value.items():
            _check_finite(v, f"{at}.{k}" if at else str(k))
    elif isinstance(value, (list, tuple)):
        for i, v in enumerate(value):
            _check_finite(v, f"{at}[{i}]")


def make_env(task: str | None = None, render_mode: str | None = None, **kwargs) -> SageEnv:
    """A :class:`SageEnv` (``task="vln"`` or ``"nogoal"`` keeps those episodes only; with no
    scene or dataset, a cached synthetic home)."""
    return SageEnv(render_mode=render_mode, task=task, **kwargs)
