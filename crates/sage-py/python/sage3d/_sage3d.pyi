# Stubs for the compiled module `sage3d._sage3d` (crates/sage-py/src/*.rs, pyo3). Names in the
# order of `__all__` (lib.rs); defaults as the `#[pyo3(signature = ...)]` attributes give them
# (or their `text_signature`, where a default is no Python literal in Rust).
# Checked against the built module by python/tests/test_stubs.py (mypy.stubtest).
#
# Dicts built from sage3d's JSON (episodes, summaries, manifests, configs, infos) are
# `dict[str, Any]`: their schemas are the files', not spelt out here.

from collections.abc import Callable, Sequence
from os import PathLike
from pathlib import Path
from typing import Any, Protocol, SupportsIndex, final

import numpy as np
from numpy.typing import NDArray
from typing_extensions import TypeAlias

__all__ = [
    "__version__",
    "Scene",
    "PathFinder",
    "Sim",
    "VecSim",
    "FolderClaim",
    "env_config",
    "read_split",
    "list_splits",
    "scenes_folder",
    "evaluate",
    "agent_spec",
    "merge_eval",
    "run_records",
    "evaluation_options",
    "dataset_claim",
    "build_scene",
    "assemble_dataset",
    "scene_dirs",
    "demo",
    "build_dataset",
    "render_training_data",
    "training_settings",
    "training_plan_scenes",
    "training_progress",
    "training_render_scene",
    "training_claim",
    "training_finish",
    "view",
]

# A path argument (Rust `PathBuf`): `str` or `os.PathLike`; paths come back as `pathlib.Path`.
_Path: TypeAlias = str | PathLike[str]
# A floor point `[x, y]` or `[x, y, z]` in the W frame (Rust `Vec<f32>`: any sequence of numbers).
_Point: TypeAlias = Sequence[float] | NDArray[Any]
# An action: an index 0-5 (discrete space) or `[stop, vx, vy, wz, dt]` / `[stop, vx, vy, vz, wz, dt]`.
_Action: TypeAlias = SupportsIndex | Sequence[float] | NDArray[Any]
# One observation (`Sim`) or a stack of them (`VecSim`): NumPy arrays under "rgb" (uint8),
# "depth" (float32), "semantic" (uint16), "instance" (uint32) and "pose" (float32), and the
# instruction ("instruction": a str, for `VecSim` a list of str).
_Obs: TypeAlias = dict[str, Any]
_Json: TypeAlias = dict[str, Any]

class _Agent(Protocol):
    # `reset(episode)` is optional and called when present.
    def act(self, obs: _Obs, /) -> _Action: ...

__version__: str

@final
class Scene:
    @staticmethod
    def load(
        path: _Path,
        cache: _Path | None = None,
        collision: _Path | None = None,
        splat_bodies: str = "auto",
    ) -> Scene: ...
    @staticmethod
    def synth(
        cache: _Path,
        seed: int = 0,
        kind: str = "home",
        rooms: int = 4,
        objects: int = 40,
        gaussians: int = 60000,
    ) -> Scene: ...
    @property
    def name(self) -> str: ...
    @property
    def path(self) -> Path: ...
    @property
    def splat_bodies(self) -> str: ...
    @property
    def num_objects(self) -> int: ...
    @property
    def num_gaussians(self) -> int: ...
    @property
    def pathfinder(self) -> PathFinder: ...
    def episodes(self, count: int = 8, seed: int = 0) -> list[_Json]: ...

@final
class PathFinder:
    def find_path(self, start: _Point, goal: _Point) -> NDArray[np.float32]: ...
    def geodesic_distance(self, a: _Point, b: _Point) -> float: ...
    def is_navigable(self, p: _Point) -> bool: ...
    def snap_point(self, p: _Point, max_distance: float = 0.5) -> NDArray[np.float32] | None: ...
    def seed(self, seed: int) -> None: ...
    def sample_navigable_point(self, island: int | None = None) -> NDArray[np.float32]: ...
    def island(self, p: _Point) -> int | None: ...
    def island_areas(self) -> list[float]: ...
    @property
    def cell_size(self) -> float: ...

@final
class Sim:
    def __new__(
        cls,
        scenes: Sequence[Scene],
        episodes: str,
        scene_of: Sequence[int],
        preset: str = "sage",
        overrides: str = "{}",
        mode: str = "sage",
    ) -> Sim: ...
    @property
    def render_device(self) -> str | None: ...
    def __len__(self) -> int: ...
    def episodes(self) -> list[_Json]: ...
    def reset(self, index: int) -> tuple[_Obs, _Json]: ...
    def step(self, action: _Action) -> tuple[_Obs, float, bool, bool, _Json]: ...

@final
class VecSim:
    def __new__(
        cls,
        num_envs: int,
        scenes: Sequence[Scene],
        episodes: str,
        scene_of: Sequence[int],
        preset: str = "sage",
        overrides: str = "{}",
        mode: str = "sage",
    ) -> VecSim: ...
    @property
    def render_device(self) -> str | None: ...
    def __len__(self) -> int: ...
    def num_episodes(self) -> int: ...
    def reset(self, indices: Sequence[int]) -> tuple[_Obs, list[_Json]]: ...
    def step(
        self, actions: Sequence[_Action], resets: Sequence[int | None]
    ) -> tuple[_Obs, NDArray[np.float32], NDArray[np.bool_], NDArray[np.bool_], list[_Json]]: ...

def env_config(preset: str = "sage", overrides: str = "{}") -> _Json: ...
def read_split(dataset: _Path, split: str) -> list[_Json]: ...
def list_splits(dataset: _Path) -> list[str]: ...
def scenes_folder(dataset: _Path, scenes: _Path | None = None) -> Path: ...
def evaluate(
    dataset: _Path,
    scenes: _Path | None,
    out: _Path,
    agent: str | Callable[[], _Agent],
    agent_name: str | None = None,
    overrides: str | None = None,
    scenes_only: Sequence[str] | None = None,
    strict: bool = False,
    report: bool = True,
    force: bool = False,
    **options: Any,
) -> _Json: ...
def agent_spec(spec: str) -> _Json: ...
def merge_eval(
    dataset: _Path,
    scenes: _Path | None,
    out: _Path,
    agent_name: str,
    shards: Sequence[str],
    overrides: str | None = None,
    python_agent: bool = False,
    **options: Any,
) -> _Json: ...
def run_records(run: _Path) -> str: ...
def evaluation_options(**options: Any) -> _Json: ...
@final
class FolderClaim:
    @property
    def out(self) -> Path: ...
    @property
    def manifest(self) -> _Json | None: ...
    @property
    def held(self) -> bool: ...
    def release(self) -> None: ...
    def __enter__(self) -> FolderClaim: ...
    def __exit__(self, _kind: object = None, _value: object = None, _traceback: object = None) -> None: ...

def dataset_claim(out: _Path, **settings: Any) -> FolderClaim: ...
def build_scene(scene_dir: _Path, out: _Path, **settings: Any) -> tuple[_Json, Path, str | None]: ...
def assemble_dataset(
    out: _Path, scenes: Sequence[_Path], root: _Path, claim: FolderClaim | None = None, **settings: Any
) -> _Json: ...
def scene_dirs(root: _Path) -> list[Path]: ...
def demo(out: _Path, **settings: Any) -> dict[str, _Json]: ...
def build_dataset(scenes: _Path, out: _Path, force: bool = False, **settings: Any) -> _Json: ...
def render_training_data(
    dataset: _Path, scenes: _Path | None, out: _Path, force: bool = False, **options: Any
) -> _Json: ...
def training_settings(dataset: _Path, scenes: _Path | None, **options: Any) -> str: ...
def training_plan_scenes(settings_json: str) -> list[str]: ...
def training_progress(settings_json: str, out: _Path) -> dict[str, _Json]: ...
def training_render_scene(settings_json: str, scene: str, out: _Path) -> _Json: ...
def training_claim(settings_json: str, out: _Path, force: bool = False) -> FolderClaim: ...
def training_finish(settings_json: str, out: _Path, claim: FolderClaim | None = None) -> _Json: ...
def view(
    path: _Path,
    *,
    scenes: _Path | None = None,
    split: str | None = None,
    play: _Path | None = None,
    force: bool = False,
    preset: str = "sage",
    mode: str = "sage",
    device: str = "cpu",
    host: str = "127.0.0.1",
    port: int = 8765,
    public: bool = False,
    on_ready: Callable[[str], object] | None = None,
) -> None: ...
