"""Checks of the arguments of sage3d's public functions. A value of the wrong type is a
``TypeError`` and a value out of range a ``ValueError``, whose message starts with the argument's
name (``what``: ``"width"``, or with the function, ``"Dataset: path"``) and says what was
expected: the errors the value would otherwise meet further on (``os.fspath``, ``float``, a
``for`` loop, the native module) name neither."""

from __future__ import annotations

import os
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np


def got(value: Any) -> str:
    """What a message says was given: the value's type name (``None`` for None)."""
    return "None" if value is None else type(value).__name__


def path(what: str, value: Any) -> str:
    """``value`` (``str`` or ``os.PathLike``) as a path string."""
    if isinstance(value, (str, os.PathLike)):
        p = os.fspath(value)
        if isinstance(p, str):
            return p
    raise TypeError(f"{what}: expected a path (str or os.PathLike), got {got(value)}")


def optional_path(what: str, value: Any) -> str | None:
    """``None``, or ``value`` as :func:`path` takes it."""
    return None if value is None else path(what, value)


def text(what: str, value: Any) -> str:
    """``value`` when it is a string."""
    if isinstance(value, str):
        return value
    raise TypeError(f"{what}: expected a string, got {got(value)}")


def flag(what: str, value: Any) -> bool:
    """``value`` when it is a bool (NumPy's too): a truthy string or number is refused rather
    than read as True."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise TypeError(f"{what}: expected True or False, got {got(value)}")


def number(what: str, value: Any) -> float:
    """``value`` as a float when it is a real number (not a bool)."""
    if isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, bool):
        return float(value)
    raise TypeError(f"{what}: expected a number, got {got(value)}")


def mapping(what: str, value: Any, of: str) -> dict:
    """``value`` as a dict when it is a mapping; ``of`` says of what (``"of EnvConfig
    fields"``)."""
    if isinstance(value, Mapping):
        return dict(value)
    raise TypeError(f"{what}: expected a dict {of}, got {got(value)}")


def whole(what: str, value: Any, least: int = 0) -> int:
    """``value`` as an int of at least ``least`` (NumPy's integers too; not a bool, nor a float
    that happens to be whole): a ``TypeError`` for any other type, as the native module's
    arguments give, and a ``ValueError`` below ``least``, where a negative count would otherwise
    reach the native module as an ``OverflowError`` that names nothing."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{what}: expected a whole number >= {least}, got {got(value)}")
    if value < least:
        raise ValueError(f"{what}: expected a whole number >= {least}, got {value!r}")
    return int(value)


def sequence(what: str, value: Any, of: str) -> list:
    """``value`` as a list when it is a collection other than a string (a string is a sequence
    too, but would be taken letter by letter); ``of`` says of what (``"of scene names"``)."""
    if isinstance(value, Iterable) and not isinstance(value, (str, bytes, Mapping)):
        return list(value)
    raise TypeError(f"{what}: expected a list {of}, got {got(value)}")
