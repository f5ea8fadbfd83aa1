"""Datasets written by ``sage3d data build``: splits, episodes and slice filters."""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Iterator

from . import _args, _sage3d

#: Episode fields a filter may name; ``assets`` and ``path`` are the complexity slices.
FILTER_KEYS = ("task", "level", "instruction_type", "subtype", "source", "scene", "assets", "path")


def _value(episode: dict, key: str):
    if key in ("assets", "path"):
        # An episode dict made by hand may lack the slices: it matches the filter value None.
        slices = episode.get("slices")
        if slices is None:
            return None
        if not isinstance(slices, dict):
            raise TypeError(f"episode {episode.get('id')!r}: slices: expected a dict of the "
                            f"complexity slices, got {_args.got(slices)}")
        return slices.get(key)
    return episode.get(key)


def check_filters(filters: dict) -> dict[str, set]:
    """The accepted values of each episode filter (see :func:`filter_episodes`), after checking
    the filters' names and the types of their values."""
    unknown = set(filters) - set(FILTER_KEYS)
    if unknown:
        raise ValueError(f"unknown episode filter {sorted(unknown)} (expected some of {list(FILTER_KEYS)})")
    accept = {}
    for k, v in filters.items():
        values = [v] if v is None or isinstance(v, str) else None
        if values is None and isinstance(v, Iterable) and not isinstance(v, (bytes, dict)):
            values = list(v)
        if values is None or not all(x is None or isinstance(x, str) for x in values):
            raise TypeError(f"{k}: expected an episode field's value (a string, or None) or a "
                            f"collection of them, got {_args.got(v)}")
        accept[k] = set(values)
    return accept


def filter_episodes(episodes: Iterable[dict], **filters) -> list[dict]:
    """The episodes whose fields match every filter.

    A filter value is one value or a collection of accepted values: ``task="vln"``,
    ``level="high"``, ``instruction_type=["Single-Goal", "Relative-Location"]``,
    ``assets="many"``, ``path="long"`` (the slices), ``scene=...``. ``None`` matches episodes
    without the field (no-goal episodes have no level).
    """
    accept = check_filters(filters)
    episodes = _args.sequence("episodes", episodes, "of episode dicts")
    for e in episodes:
        if not isinstance(e, dict):
            raise TypeError(f"episodes: expected a list of episode dicts, got a list holding "
                            f"{_args.got(e)}")
    return [e for e in episodes if all(_value(e, k) in ok for k, ok in accept.items())]


class Dataset:
    """A dataset folder: ``episodes/{split}.jsonl``, ``splits.json``, ``summary.json``."""

    def __init__(self, path: str | os.PathLike):
        self.path = _args.path("Dataset: path", path)
        self.splits = _sage3d.list_splits(self.path)

    def episodes(self, split: str = "train", **filters) -> list[dict]:
        """The episodes of ``split`` (dicts in the JSONL schema), filtered as
        :func:`filter_episodes`."""
        split = _args.text("Dataset.episodes: split", split)
        # Before the split is read, so that a bad filter is named whatever the split holds.
        check_filters(filters)
        return filter_episodes(_sage3d.read_split(self.path, split), **filters)

    def __iter__(self) -> Iterator[tuple[str, list[dict]]]:
        """``(split, episodes)`` for every split, in name order."""
        for split in self.splits:
            yield split, self.episodes(split)

    def summary(self) -> dict:
        """The dataset's ``summary.json`` (counts per split, type and slice)."""
        with open(os.path.join(self.path, "summary.json")) as f:
            return json.load(f)

    def __repr__(self) -> str:
        return f"Dataset({self.path!r}, splits={self.splits})"


def load_dataset(path: str | os.PathLike) -> Dataset:
    """Opens a dataset folder written by ``sage3d data build``."""
    return Dataset(_args.path("load_dataset: path", path))
