"""Reading one value of a scene table, checked: a number (finite, signed, bounded, integral as
asked), a vector of numbers, a list of number tuples, one of a set of choices, a list of integers;
and the one error every rejection raises, :class:`SceneError`, whose message names the key and the
value. :mod:`jaxbelt.scene` reads every table through these."""

from __future__ import annotations

import math
from typing import Any


class SceneError(ValueError):
    """A scene that cannot be simulated; the message names the key and the value."""


def key_error(key: str, value: Any, why: str) -> SceneError:
    return SceneError(f"{key} = {value!r}: {why}")


def check_keys(table: dict, allowed: set, where: str):
    for k in table:
        if k not in allowed:
            raise key_error(f"{where}.{k}", table[k], f"unknown key (allowed: {', '.join(sorted(allowed))})")


def number(d: dict, key: str, where: str, *, required=True, default=None, positive=False, nonneg=False,
            integer=False, lo=None, hi=None):
    if key not in d:
        if required:
            raise key_error(f"{where}.{key}", None, "required key is missing")
        return default
    v = d[key]
    name = f"{where}.{key}"
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise key_error(name, v, "must be a number")
    if integer and not isinstance(v, int):
        raise key_error(name, v, "must be an integer")
    if not math.isfinite(v):
        raise key_error(name, v, "must be finite (no NaN or inf)")
    if positive and not v > 0:
        raise key_error(name, v, "must be positive")
    if nonneg and v < 0:
        raise key_error(name, v, "must not be negative")
    if lo is not None and v < lo:
        raise key_error(name, v, f"must be >= {lo}")
    if hi is not None and v >= hi:
        raise key_error(name, v, f"must be < {hi}")
    return v


def vector(d: dict, key: str, where: str, n: int, default=None):
    if key not in d:
        if default is None:
            raise key_error(f"{where}.{key}", None, "required key is missing")
        return tuple(default)
    v = d[key]
    name = f"{where}.{key}"
    if not isinstance(v, list) or len(v) != n:
        raise key_error(name, v, f"must be a list of {n} numbers")
    for x in v:
        if isinstance(x, bool) or not isinstance(x, (int, float)):
            raise key_error(name, v, "must be a list of numbers")
        if not math.isfinite(x):
            raise key_error(name, v, "must be finite (no NaN or inf)")
    return tuple(float(x) for x in v)


def number_tuples(d: dict, key: str, where: str, n: int, what: str) -> list:
    """``d[key]`` as a list of lists of ``n`` finite numbers each (``[]`` when absent), else a
    :class:`SceneError` naming the key: "must be a list of ``what`` of finite numbers"."""
    v = d.get(key, [])
    ok = isinstance(v, list) and all(
        isinstance(t, list) and len(t) == n and all(isinstance(x, (int, float)) and not isinstance(x, bool)
                                                     and math.isfinite(x) for x in t) for t in v)
    if not ok:
        raise key_error(f"{where}.{key}", v, f"must be a list of {what} of finite numbers")
    return v


def _toml(c) -> str:
    """A choice as the scene file spells it (``true``/``false`` for booleans)."""
    return str(c).lower() if isinstance(c, bool) else str(c)


def choice(d: dict, key: str, where: str, choices, default=None):
    """``d[key]``, one of ``choices`` (of the same type: ``1`` is not ``true``), else ``default``
    where given; a missing required key or another value is a :class:`SceneError`."""
    names = ", ".join(_toml(c) for c in choices)
    if key not in d:
        if default is None:
            raise key_error(f"{where}.{key}", None, f"required key is missing (one of {names})")
        return default
    v = d[key]
    if not any(type(v) is type(c) and v == c for c in choices):
        raise key_error(f"{where}.{key}", v, f"must be one of {names}")
    return v


def int_list(d: dict, key: str, where: str, n: int):
    if key not in d:
        return None
    v = d[key]
    if not isinstance(v, list) or len(v) != n or not all(isinstance(x, int) and not isinstance(x, bool) for x in v):
        raise key_error(f"{where}.{key}", v, f"must be a list of {n} integers (one per roller)")
    return tuple(v)
