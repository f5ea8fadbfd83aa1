"""Training sets written by ``sage3d data render`` (or :func:`sage3d.render_training_data`),
read back as NumPy arrays, one episode in memory at a time.

A render's folder holds ``manifest.json`` (written last: its presence means the render
finished), whose ``settings.format`` names one of three layouts:

``navila``
    NaVILA's training format. ``annotations_part_NNN.json``: a shuffled list of per-step
    samples ``{"video_id": "{episode_id}-{step}", "q": instruction, "a": "The next action is
    move forward 0.35 meter.", "frames": [the RGB frames from the start to this step]}``, frame
    paths relative to ``images/``; ``dataset_info.json``; and the frames under
    ``images/{scene}/{route}/{k:04}.{jpg|png}`` beside each route's ``route.json`` (the walk:
    per action its name, the frame's pose, the commanded and the achieved pose). Depth,
    semantic and instance images sit beside the RGB frame as ``{k:04}.depth.png``, …
``webdataset``
    Tar shards ``shards/{split}-NNNNNN.tar``, one sample per episode: members
    ``{key}.{k:04}.jpg`` (``.depth.png``, …) per frame and ``{key}.json`` (the episode record
    below with its ``files`` named by field, ``0003.jpg``), ``key`` the episode id's file
    name: the id itself when it is lower-case letters, digits, ``-`` and ``_``; otherwise the
    id's first characters lower-cased, every other character replaced by ``_``, then ``-`` and
    16 hex digits of a hash of the id (distinct ids keep distinct keys, none holding a dot).
``frames``
    ``episodes.jsonl``, one episode record per line, and the frames under ``images/``.

The episode record (``episodes.jsonl``, the shards' ``json``): ``episode_id``, ``scene``,
``instruction``, ``route``, ``verdict``, ``ending``, ``actions`` (``MOVE_FORWARD``,
``TURN_LEFT``, ``TURN_RIGHT``, ``STOP`` last), ``words`` (``move forward 0.35 meter``, …),
``files`` (per frame, RGB first) and ``steps`` (per action ``action``, ``pose``,
``commanded``, ``achieved`` as ``[x, y, yaw]`` in the W frame, metres and radians, and
``contact``). Frame ``k`` is the camera's view before action ``k``, so an episode has as many
frames as actions.

Images are decoded with Pillow. Depth is stored as 16-bit PNG in millimetres (0 where nothing
was hit) and read as float32 metres. PyTorch is optional: ``sage3d.training.TorchDataset``
imports it when first used.
"""

from __future__ import annotations

import io
import json
import os
import tarfile
from typing import Any, Callable, Iterator

import numpy as np

from . import _args

MANIFEST = "manifest.json"
IMAGES_DIR = "images"
ROUTE_FILE = "route.json"

#: The discrete actions by index, as the environment's ``Discrete(4)`` numbers them.
ACTIONS = ("STOP", "MOVE_FORWARD", "TURN_LEFT", "TURN_RIGHT")

_ACTION_WORDS = (("move forward", "MOVE_FORWARD"), ("turn left", "TURN_LEFT"),
                 ("turn right", "TURN_RIGHT"), ("stop", "STOP"))
_ANSWER_PREFIX = "The next action is "
_EXTRA = ("depth", "semantic", "instance")


def _image_module():
    try:
        from PIL import Image
    except ImportError as e:  # pragma: no cover - depends on the installation
        raise ImportError("sage3d.training decodes frames with Pillow: pip install pillow") from e
    return Image


def decode_rgb(data: bytes) -> np.ndarray:
    """A JPEG or PNG frame as a uint8 array (H, W, 3)."""
    with _image_module().open(io.BytesIO(data)) as im:
        return np.asarray(im.convert("RGB"), dtype=np.uint8)


def decode_u16(data: bytes) -> np.ndarray:
    """A 16-bit grayscale PNG (depth in millimetres, semantic or instance ids) as a uint16
    array (H, W)."""
    with _image_module().open(io.BytesIO(data)) as im:
        a = np.asarray(im)
    if a.ndim != 2:
        raise ValueError(f"expected a single-channel 16-bit PNG, got an image of shape {a.shape}")
    return a.astype(np.uint16, copy=False)


def decode_depth(data: bytes) -> np.ndarray:
    """A depth frame (16-bit PNG, millimetres) as float32 metres (H, W); 0 where nothing was
    hit."""
    return decode_u16(data).astype(np.float32) / np.float32(1000.0)


def action_of_words(words: str) -> str:
    """The action name (``MOVE_FORWARD``, ``TURN_LEFT``, ``TURN_RIGHT``, ``STOP``) of an action
    in NaVILA's words (``move forward 0.35 meter``, ``turn left 30 degree``, ``stop``)."""
    for prefix, name in _ACTION_WORDS:
        if words == prefix or words.startswith(prefix + " "):
            return name
    raise ValueError(f"not an action in words: {words!r}")


def words_of_answer(answer: str) -> str:
    """The action words of a NaVILA answer: ``The next action is turn left 30 degree.`` gives
    ``turn left 30 degree``."""
    if not (answer.startswith(_ANSWER_PREFIX) and answer.endswith(".")):
        raise ValueError(f"not a NaVILA answer: {answer!r}")
    return answer[len(_ANSWER_PREFIX):-1]


def _kind(name: str) -> str:
    """Which image a frame file holds, from its name: ``rgb``, ``depth``, ``semantic`` or
    ``instance``."""
    for kind in _EXTRA:
        if name.endswith(f".{kind}.png"):
            return kind
    return "rgb"


class TrainingSet:
    """A finished training-data render, read with NumPy.

    ``TrainingSet(path)`` reads ``path/manifest.json`` and detects the layout from its
    ``settings.format`` (``navila``, ``webdataset`` or ``frames``; see the module's
    documentation). ``len()`` is the number of episodes kept; iterating is :meth:`episodes`.
    """

    def __init__(self, path):
        self.path = _args.path("TrainingSet: path", path)
        manifest = os.path.join(self.path, MANIFEST)
        if not os.path.isfile(manifest):
            raise FileNotFoundError(
                f"{manifest} is missing: not a finished training-data render (a render writes "
                "its manifest last; run it again to finish it)")
        with open(manifest) as f:
            #: The manifest (``manifest.json``): settings, counts, skipped episodes, files.
            self.manifest: dict = json.load(f)
        #: The render's settings as the manifest records them.
        self.settings: dict = self.manifest.get("settings", {})
        #: The layout: ``navila``, ``webdataset`` or ``frames``.
        self.format: str = self.settings.get("format", "")
        if self.format == "lerobot":
            raise ValueError(f"{manifest}: a LeRobot dataset: read it with LeRobot's own loader "
                             "(lerobot.datasets.lerobot_dataset.LeRobotDataset; docs/training-data.md)")
        if self.format not in ("navila", "webdataset", "frames"):
            raise ValueError(f"{manifest}: unknown training-set format {self.format!r}")

    def __len__(self) -> int:
        return int(self.manifest["counts"]["kept"])

    def __iter__(self) -> Iterator[dict]:
        return self.episodes()

    def __repr__(self) -> str:
        return f"TrainingSet({self.path!r}, format={self.format!r}, episodes={len(self)})"

    def _files(self, prefix: str) -> list:
        return [f["path"] for f in self.manifest.get("files", []) if f["path"].startswith(prefix)]

    def episodes(self, images: bool = True, shard: tuple | None = None) -> Iterator[dict]:
        """Yields the episodes, one at a time, as dicts:

        - ``episode_id``, ``scene``, ``route``, ``instruction``, ``verdict``, ``ending``;
        - ``actions``: ``MOVE_FORWARD`` / ``TURN_LEFT`` / ``TURN_RIGHT`` / ``STOP`` (last);
          ``words``: each in NaVILA's words (``move forward 0.35 meter``);
        - ``rgb``: uint8 (T, H, W, 3), frame ``k`` taken before action ``k`` (T = number of
          actions); when rendered: ``depth`` float32 metres (T, h, w), 0 where nothing was
          hit, ``semantic`` and ``instance`` uint16 (T, H, W);
        - ``poses``, ``commanded``, ``achieved``: float32 (T, 3) ``[x, y, yaw]`` (W frame,
          metres, radians): each frame's pose, where its action was meant to take the agent
          and where physics put it; ``contact``: bool (T,), the agent touched something.

        Order: ``frames`` and ``webdataset`` in file order (scenes sorted, routes in dataset
        order); ``navila`` (whose parts are shuffled) by scene, route and episode id.
        ``images=False`` skips the image files (no image keys). ``shard=(i, n)`` yields only
        the episodes at positions i, i + n, i + 2n, … (one data-loader worker's share).
        """
        # Checked here, outside the generator, so that a bad argument fails the call itself
        # rather than the first step of the iteration.
        images = _args.flag("TrainingSet.episodes: images", images)
        part = _shard("TrainingSet.episodes: shard", shard)
        return (_public(ep) for ep in self._episodes(images, part))

    def _episodes(self, images: bool, shard: tuple[int, int] | None) -> Iterator[dict]:
        readers = {"navila": self._navila, "webdataset": self._webdataset,
                   "frames": self._frames}
        for pos, (record, read) in enumerate(readers[self.format]()):
            if shard is not None and pos % shard[1] != shard[0]:
                continue
            yield _episode(record, read if images else None)

    def samples(self, shard: tuple | None = None) -> Iterator[dict]:
        """Yields NaVILA-style per-step samples, episode by episode (each episode's frames
        decoded once): ``video_id`` (``{episode_id}-{step}``), ``episode_id``, ``step``, ``q``
        (the instruction), ``a`` (``The next action is move forward 0.35 meter.``) and
        ``frames``: uint8 (step + 1, H, W, 3), the frames from the start to this step (a view
        of the episode's array); ``depth`` likewise when rendered. For the ``navila`` layout
        the question, the answer and the frame count are the annotation parts' own (the
        order is not their shuffled one). ``shard`` as in :meth:`episodes`.
        """
        return self._samples(_shard("TrainingSet.samples: shard", shard))

    def _samples(self, shard: tuple[int, int] | None) -> Iterator[dict]:
        for ep in self._episodes(True, shard):
            # The NaVILA layout's own question, answers and frame counts, else the record's.
            navila = ep.pop("_navila", None) or {
                "question": ep["instruction"],
                "answers": [f"{_ANSWER_PREFIX}{w}." for w in ep["words"]],
                "frame_counts": list(range(1, len(ep["actions"]) + 1))}
            question, answers, counts = (navila[k] for k in ("question", "answers", "frame_counts"))
            for k, (a, n) in enumerate(zip(answers, counts)):
                s = {"video_id": f"{ep['episode_id']}-{k}", "episode_id": ep["episode_id"],
                     "step": k, "q": question, "a": a, "frames": ep["rgb"][:n]}
                if "depth" in ep:
                    s["depth"] = ep["depth"][:n]
                yield s

    # The layouts: each yields (episode record, read(name) -> bytes) in episode order.

    def _frames(self):
        images = os.path.join(self.path, IMAGES_DIR)

        def read(name):
            with open(os.path.join(images, name), "rb") as f:
                return f.read()

        with open(os.path.join(self.path, "episodes.jsonl")) as f:
            for line in f:
                if line.strip():
                    yield json.loads(line), read

    def _webdataset(self):
        for shard in self._files("shards/"):
            path = os.path.join(self.path, shard)
            # Streaming mode: one member after the other, one episode's members held at a time.
            with tarfile.open(path, mode="r|") as tar:
                key, group = None, {}
                for member in tar:
                    if not member.isfile():
                        continue
                    k, _, field = os.path.basename(member.name).partition(".")
                    if k != key:
                        if group:
                            yield _wds_sample(path, key, group)
                        key, group = k, {}
                    group[field] = tar.extractfile(member).read()
                if group:
                    yield _wds_sample(path, key, group)

    def _navila(self):
        images = os.path.join(self.path, IMAGES_DIR)
        episodes: dict = {}
        for part in self._files("annotations_part_"):
            with open(os.path.join(self.path, part)) as f:
                samples = json.load(f)
            for s in samples:
                _add_navila_sample(episodes, s, part)

        def read(name):
            with open(os.path.join(images, name), "rb") as f:
                return f.read()

        def route_of(ep):
            frames = ep["frames"]
            parts = frames[0].split("/") if frames else []
            if len(parts) != 3:
                raise ValueError(f"episode {ep['id']}: unexpected frame path {frames[:1]!r}")
            return parts[0], parts[1]

        order = sorted(episodes.values(), key=lambda ep: (*route_of(ep), ep["id"]))
        cached = (None, None)
        for ep in order:
            scene, route = route_of(ep)
            if cached[0] != (scene, route):
                path = os.path.join(images, scene, route, ROUTE_FILE)
                with open(path) as f:
                    cached = ((scene, route), json.load(f))
            yield _navila_record(ep, scene, route, cached[1]), read


def _shard(what: str, shard: Any) -> tuple[int, int] | None:
    """``shard`` as ``(i, n)``, two whole numbers with 0 <= i < n, or None."""
    if shard is None:
        return None
    if not (isinstance(shard, (tuple, list)) and len(shard) == 2
            and all(isinstance(k, (int, np.integer)) and not isinstance(k, bool) for k in shard)):
        raise TypeError(f"{what}: expected (i, n), two whole numbers, got {_args.got(shard)}")
    i, n = int(shard[0]), int(shard[1])
    if not (0 <= i < n):
        raise ValueError(f"{what}: expected (i, n) with 0 <= i < n, got {shard!r}")
    return i, n


def _public(ep: dict) -> dict:
    """An episode as :meth:`TrainingSet.episodes` yields it: without the NaVILA layout's own
    question, answers and frame counts, which only :meth:`TrainingSet.samples` reads."""
    ep.pop("_navila", None)
    return ep


def _wds_sample(path, key, group):
    if "json" not in group:
        raise ValueError(f"{path}: sample {key!r} has no json member")
    record = json.loads(group["json"])

    def read(name):
        try:
            return group[name]
        except KeyError:
            raise ValueError(f"{path}: sample {key!r} has no member {key}.{name}") from None

    return record, read


def _add_navila_sample(episodes: dict, s: dict, part: str):
    """Adds one annotation sample to its episode, keeping only the longest frame list (the
    others are checked to be its prefixes)."""
    ep_id, sep, step = s["video_id"].rpartition("-")
    if not sep or not step.isdigit():
        raise ValueError(f"{part}: video_id {s['video_id']!r} is not '{{episode_id}}-{{step}}'")
    k = int(step)
    ep = episodes.setdefault(ep_id, {"id": ep_id, "q": s["q"], "answers": {}, "counts": {},
                                     "frames": []})
    if s["q"] != ep["q"]:
        raise ValueError(f"{part}: {s['video_id']}: the question differs from the episode's")
    frames, longest = s["frames"], ep["frames"]
    short, long = (frames, longest) if len(frames) <= len(longest) else (longest, frames)
    if long[:len(short)] != short:
        raise ValueError(f"{part}: {s['video_id']}: its frames are not a prefix of the "
                         "episode's other samples' frames")
    ep["frames"] = long
    ep["answers"][k] = s["a"]
    ep["counts"][k] = len(frames)


def _navila_record(ep: dict, scene: str, route: str, route_record: dict) -> dict:
    """The episode record of a NaVILA episode: its annotation samples with the walk of its
    route's ``route.json``."""
    steps = sorted(ep["answers"])
    n = len(ep["frames"])
    if steps != list(range(n)) or any(ep["counts"][k] != k + 1 for k in steps):
        raise ValueError(f"episode {ep['id']}: expected one sample per step 0..{n - 1} with "
                         "step + 1 frames each")
    walk = route_record.get("walk") or {}
    if len(walk.get("steps", [])) != n:
        raise ValueError(f"episode {ep['id']}: {n} frames, but its route's walk has "
                         f"{len(walk.get('steps', []))} steps")
    answers = [ep["answers"][k] for k in steps]
    words = [words_of_answer(a) for a in answers]
    suffixes = route_record.get("suffixes", [])
    files = []
    for f in ep["frames"]:
        stem = f.rsplit(".", 1)[0]
        files.append([f] + [f"{stem}.{s}" for s in suffixes[1:]])
    return {"episode_id": ep["id"], "scene": scene, "instruction": ep["q"], "route": route,
            "verdict": walk.get("verdict"), "ending": walk.get("ending"),
            "actions": [action_of_words(w) for w in words], "words": words, "files": files,
            "steps": walk["steps"],
            "_navila": {"question": ep["q"], "answers": answers,
                        "frame_counts": [ep["counts"][k] for k in steps]}}


def _episode(record: dict, read: Callable[[str], bytes] | None) -> dict:
    """An episode dict from its record, decoding its frame files through ``read`` (none when
    ``read`` is None)."""
    steps = record["steps"]
    if len(steps) != len(record["actions"]) or len(record["files"]) != len(steps):
        raise ValueError(f"episode {record.get('episode_id')}: {len(record['actions'])} actions, "
                         f"{len(record['files'])} frames and {len(steps)} steps differ")
    out: dict[str, Any] = {k: record.get(k) for k in
                           ("episode_id", "scene", "route", "instruction", "verdict", "ending")}
    out["actions"] = list(record["actions"])
    out["words"] = list(record["words"])
    if "_navila" in record:
        out["_navila"] = record["_navila"]
    if read is not None:
        decoded: dict[str, list] = {}
        for frame in record["files"]:
            for name in frame:
                kind = _kind(name)
                data = read(name)
                if kind == "rgb":
                    img = decode_rgb(data)
                elif kind == "depth":
                    img = decode_depth(data)
                else:
                    img = decode_u16(data)
                decoded.setdefault(kind, []).append(img)
        for kind in ("rgb", *_EXTRA):
            if kind in decoded:
                out[kind] = np.stack(decoded[kind])
    for key, field in (("poses", "pose"), ("commanded", "commanded"), ("achieved", "achieved")):
        out[key] = np.asarray([s[field] for s in steps], dtype=np.float32).reshape(len(steps), 3)
    out["contact"] = np.asarray([bool(s.get("contact")) for s in steps], dtype=bool)
    return out


def _torch_dataset_class():
    try:
        # PyTorch is optional: without it installed, mypy has nothing to check these against.
        import torch  # type: ignore[import-not-found, unused-ignore]
        from torch.utils.data import (  # type: ignore[import-not-found, unused-ignore]
            IterableDataset, get_worker_info)
    except ImportError as e:
        raise ImportError("sage3d.training.TorchDataset needs PyTorch: pip install torch") from e

    class TorchDataset(IterableDataset):
        """A training set as a ``torch.utils.data.IterableDataset`` of episodes (streamed: one
        episode decoded at a time; a data loader's workers each take every n-th episode).

        Each item is a dict: ``episode_id``, ``instruction``, ``words`` (str, list of str),
        ``rgb`` uint8 (T, 3, H, W) (``channels_first=False``: (T, H, W, 3)), ``actions``
        int64 (T,) as the environment numbers them (0 STOP, 1 MOVE_FORWARD, 2 TURN_LEFT,
        3 TURN_RIGHT), ``poses``, ``commanded``, ``achieved`` float32 (T, 3) and, when
        rendered, ``depth`` float32 metres (T, h, w), ``semantic`` and ``instance`` int32
        (T, H, W). ``transform(item)``, when given, maps each item. Episodes differ in
        length: use ``batch_size=None`` or a ``collate_fn`` that pads.
        """

        def __init__(self, path, transform: Callable | None = None,
                     channels_first: bool = True):
            super().__init__()
            if transform is not None and not callable(transform):
                raise TypeError(f"TorchDataset: transform: expected a callable or None, got "
                                f"{_args.got(transform)}")
            self.training_set = TrainingSet(path)
            self.transform = transform
            self.channels_first = _args.flag("TorchDataset: channels_first", channels_first)

        def __len__(self) -> int:
            return len(self.training_set)

        def __iter__(self):
            info = get_worker_info()
            shard = None if info is None else (info.id, info.num_workers)
            for ep in self.training_set.episodes(shard=shard):
                rgb = torch.from_numpy(ep["rgb"])
                if self.channels_first:
                    rgb = rgb.permute(0, 3, 1, 2).contiguous()
                item = {"episode_id": ep["episode_id"], "instruction": ep["instruction"],
                        "words": ep["words"], "rgb": rgb,
                        "actions": torch.tensor([ACTIONS.index(a) for a in ep["actions"]],
                                                dtype=torch.int64)}
                for key in ("poses", "commanded", "achieved", "depth"):
                    if key in ep:
                        item[key] = torch.from_numpy(ep[key])
                for key in ("semantic", "instance"):
                    if key in ep:
                        # torch has no uint16 arithmetic on every version; the ids fit int32.
                        item[key] = torch.from_numpy(ep[key].astype(np.int32))
                yield self.transform(item) if self.transform is not None else item

    TorchDataset.__module__ = __name__
    TorchDataset.__qualname__ = "TorchDataset"
    return TorchDataset


def __getattr__(name):
    # TorchDataset is made on first use, so that importing this module never imports torch.
    if name == "TorchDataset":
        cls = _torch_dataset_class()
        globals()["TorchDataset"] = cls
        return cls
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
