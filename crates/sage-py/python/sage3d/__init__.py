"""sage3d from Python: executable 3D Gaussian Splatting scenes for vision-and-language navigation.

- ``make_env()`` / ``gymnasium.make("SageVLN-v0")``: a Gymnasium environment with NumPy
  observations (a synthetic scene when no data is given), ``make_vec_env()`` its vector form.
- ``Scene.load(dir)`` / ``synth_scene()``: scenes with their path finder (``scene.pathfinder``).
- ``load_dataset(dir)``: datasets written by ``sage3d data build``; episodes by split and slice.
- ``evaluate(...)``: the evaluator of ``sage3d eval`` with built-in or Python agents.
- ``demo(out)`` / ``build_dataset(scenes, out)``: the pipelines of ``sage3d demo`` and
  ``sage3d data build``, the same library functions the command line calls.
- ``render_training_data(dataset, scenes, out)`` / ``TrainingSet(out)``: training data for VLN
  models as ``sage3d data render`` writes it (NaVILA, WebDataset or frames), and its reader
  (``sage3d.training``, with a PyTorch dataset when torch is installed).
- ``view(path)``: the browser viewer of ``sage3d view`` (map, first-person view, keyboard
  driving, the episodes of a run step by step, human play with ``play=RUN``).
- ``sage3d.distributed``: dataset generation, evaluation and training-data rendering sharded
  over a Ray cluster.
"""

import gymnasium

from ._sage3d import (
    PathFinder,
    Scene,
    __version__,
    build_dataset,
    demo,
    env_config,
    render_training_data,
    view,
)
from .dataset import Dataset, filter_episodes, load_dataset
from .env import SageEnv, cache_dir, make_env, synth_scene
from .evaluation import evaluate
from .training import TrainingSet
from .vector import SageVectorEnv, make_vec_env

__all__ = [
    "Dataset",
    "PathFinder",
    "SageEnv",
    "SageVectorEnv",
    "Scene",
    "TrainingSet",
    "__version__",
    "build_dataset",
    "cache_dir",
    "demo",
    "env_config",
    "evaluate",
    "filter_episodes",
    "load_dataset",
    "make_env",
    "make_vec_env",
    "render_training_data",
    "synth_scene",
    "view",
]

for _id, _task in (("SageVLN-v0", "vln"), ("SageNoGoal-v0", "nogoal")):
    if _id not in gymnasium.registry:
        gymnasium.register(
            id=_id,
            entry_point="sage3d.env:SageEnv",
            vector_entry_point="sage3d.vector:SageVectorEnv",
            kwargs={"task": _task},
        )
