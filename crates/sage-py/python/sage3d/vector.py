"""Several sage3d environments stepped in parallel in Rust in one call (GIL released), as a
Gymnasium ``VectorEnv`` with next-step autoreset."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
from gymnasium.error import ClosedEnvironmentError
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from . import _args, _sage3d
from ._args import whole
from .env import _json, _Prepared, action_space, check_discrete, check_options, observation_space


class SageVectorEnv(_Prepared, VectorEnv):
    """``num_envs`` environments over one episode pool (the keyword arguments of
    :class:`~sage3d.SageEnv`), stepped together by rayon.

    Sub-environment ``i`` draws its episodes with a generator seeded ``seed + i`` at
    ``reset(seed=seed)``, as ``gymnasium.vector.SyncVectorEnv`` seeds its copies, so the two give
    the same episodes, observations and rewards. Autoreset is ``NEXT_STEP``: the step after a
    sub-environment's episode ends resets it (reward 0, not terminated, its action ignored).
    Observations are stacked along a first axis; ``instruction`` is a tuple of strings.
    With ``device="gpu"`` (or ``"auto"`` on a hardware GPU) the sub-environments over a scene
    render from one upload of it, their cameras in one batch per step.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 4, "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 2, render_mode: str | None = None, *, scene=None,
                 dataset=None, scenes=None, split: str = "train", episodes=None,
                 task: str | None = None, filters: dict | None = None, num_episodes: int = 8,
                 seed: int = 0, synth: dict | None = None, preset: str = "sage",
                 width: int | None = None, height: int | None = None,
                 sensors: Iterable[str] | None = None, actions: str = "discrete",
                 look: bool = False, max_steps: int | None = None, hfov: float | None = None,
                 config: dict | None = None, mode: str = "sage", device: str = "cpu"):
        num_envs = whole("num_envs", num_envs, 1)
        overrides, pool_scenes, eps, scene_of = self._prepare(
            render_mode, scene, dataset, scenes, split, episodes, task, filters, num_episodes,
            seed, synth, preset, width, height, sensors, actions, look, max_steps, hfov, config,
            mode, device)
        self._sim = _sage3d.VecSim(num_envs, pool_scenes, _json(eps), scene_of, preset,
                                   overrides, mode)
        self.num_envs = num_envs
        self.single_observation_space = observation_space(self.config, (e["instruction"] for e in eps))
        self.single_action_space = action_space(self.config, look)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self._rngs = [seeding.np_random(None)[0] for _ in range(num_envs)]
        self._autoreset = np.zeros(num_envs, dtype=bool)
        self._last: dict[str, Any] | None = None

    @property
    def render_device(self) -> str | None:
        """Which renderer forms the images (as :attr:`sage3d.SageEnv.render_device`)."""
        return self._sim.render_device

    def _draw(self, i: int) -> int:
        return int(self._rngs[i].integers(self._sim.num_episodes()))

    def _batch(self, obs: dict, infos: list[dict]):
        obs["instruction"] = tuple(obs["instruction"])
        self._last = obs
        vector_infos: dict = {}
        for i, info in enumerate(infos):
            vector_infos = self._add_info(vector_infos, info, i)
        return obs, vector_infos

    #: The keys ``reset(options=...)`` accepts; any other is a ``ValueError``.
    RESET_OPTIONS = ("episode_index",)

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        """Resets every sub-environment; ``seed`` an int (sub-environment ``i`` gets
        ``seed + i``) or one per sub-environment; ``options={"episode_index": [...]}`` picks
        the episodes (any other key is a ``ValueError``)."""
        self._check_open()
        # Everything is checked before the generators are reseeded, so a refused call changes
        # nothing.
        options = check_options(options, self.RESET_OPTIONS)
        indices = None
        if "episode_index" in options:
            given = options["episode_index"]
            if not isinstance(given, Iterable) or isinstance(given, (str, bytes)):
                raise ValueError(f"episode_index: expected one index per sub-environment, got {given!r}")
            indices = [whole("episode_index", k) for k in given]
            if len(indices) != self.num_envs:
                raise ValueError(f"episode_index: expected {self.num_envs} indices, one per "
                                 f"sub-environment, got {len(indices)}")
            pool = self._sim.num_episodes()
            for i, k in enumerate(indices):
                if k >= pool:
                    raise ValueError(f"episode_index[{i}]: {k} is past this env's {pool} episodes")
        if seed is not None:
            seeds: list[Any]
            if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
                seeds = [int(seed) + i for i in range(self.num_envs)]
            else:
                seeds = _args.sequence("seed", seed, "of seeds (one per sub-environment), or an int")
            if len(seeds) != self.num_envs:
                raise ValueError(f"seed: expected {self.num_envs} seeds (one per sub-environment), "
                                 f"got {len(seeds)}")
            seeds = [None if s is None else whole("seed", s) for s in seeds]
            for i, s in enumerate(seeds):
                if s is not None:
                    self._rngs[i] = seeding.np_random(s)[0]
        if indices is None:
            indices = [self._draw(i) for i in range(self.num_envs)]
        obs, infos = self._sim.reset(indices)
        self._autoreset[:] = False
        return self._batch(obs, infos)

    def step(self, actions):
        self._check_open()
        batch = _args.sequence("actions", actions, "of actions (one per sub-environment)")
        if len(batch) != self.num_envs:
            raise ValueError(f"actions: expected {self.num_envs} actions, one per sub-environment, "
                             f"got {len(batch)}")
        check_discrete(self.action_space, actions, "actions")
        resets = [self._draw(i) if done else None for i, done in enumerate(self._autoreset)]
        obs, rewards, terminated, truncated, infos = self._sim.step(batch, resets)
        self._autoreset = terminated | truncated
        obs, infos = self._batch(obs, infos)
        return obs, rewards.astype(np.float64), terminated, truncated, infos

    def _check_open(self):
        # As Gymnasium's own vector environments: a closed one is not stepped again.
        if self.closed:
            raise ClosedEnvironmentError("the vector environment is closed")

    def render(self):
        """The last RGB observations, ``(num_envs, H, W, 3)`` uint8 (``render_mode="rgb_array"``)."""
        if self.render_mode is None or self._last is None:
            return None
        return self._last["rgb"]


def make_vec_env(num_envs: int = 2, task: str | None = None, render_mode: str | None = None,
                 **kwargs) -> SageVectorEnv:
    """A :class:`SageVectorEnv` of ``num_envs`` sub-environments (keyword arguments as
    :func:`sage3d.make_env`)."""
    return SageVectorEnv(num_envs, render_mode=render_mode, task=task, **kwargs)
