"""The one serialisation convention of jaxbelt's typed results.

Every result is a frozen dataclass whose fields carry their unit in their name (``_um``, ``_mrad``,
``_s``, ``_mm_s_per_mrad``: SI with a prefix, micrometres wherever a belt position is reported),
holds typed values (nested results are dataclasses, not dicts), and turns into JSON-able data by
:func:`to_json`: nested dataclasses become objects, arrays and tuples lists, numpy scalars Python
numbers, and a non-finite float ``null`` (JSON has no ``inf`` or ``nan``; a margin that does not
exist, a run that diverged). A result that presents itself differently in JSON (a renamed key,
rows built from parallel arrays) says so in its own ``to_dict``, which still ends in
:func:`to_json`.

A design result's metric values are in the metric's unit, which the record names in its ``unit``
field (µm for the belt-position metrics, mrad for ``steering_max``, µm/s for ``walk_rate``). Such
a field is declared with :func:`in_metric_unit` and named for the µm case in Python
(``worst_case_um``); in JSON its key names the record's unit (:func:`unit_key`:
``worst_case_mrad`` in a ``steering_max`` box), so a key never names a unit its value is not in.
"""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np


UNIT_SUFFIXES = {"µm": "um", "mrad": "mrad", "µm/s": "um_per_s"}  # a metric unit as it appears in a key


def in_metric_unit(**kwargs):
    """A dataclass field whose values are in the record's ``unit`` (module docstring); ``kwargs``
    as :func:`dataclasses.field`."""
    return dataclasses.field(metadata={"in_metric_unit": True}, **kwargs)


def unit_field(default: str = "µm"):
    """The ``unit`` field of a record nested in another that names the unit (a verification run
    of a tolerance box, a roller's sensitivities): left out of the JSON, whose keys name it."""
    return not_in_json(default)


def not_in_json(default=None):
    """A dataclass field the record's JSON leaves out (the inputs a record keeps for the code that
    reads it further, which the JSON names another way: a sweep's configurations, by its seed)."""
    return dataclasses.field(default=default, metadata={"in_json": False})


def unit_key(name: str, unit: str) -> str:
    """The JSON key of the metric-valued field ``name`` (named for µm: ``limit_um``,
    ``translation_um_per_mm``) in a record whose values are in ``unit``: its ``_um`` part names
    ``unit`` instead (``limit_mrad``, ``translation_um_per_s_per_mm``)."""
    if unit not in UNIT_SUFFIXES:
        raise ValueError(f"unit = {unit!r}: not a metric unit (one of {', '.join(UNIT_SUFFIXES)})")
    key, n = re.subn(r"_um(?=_|$)", "_" + UNIT_SUFFIXES[unit], name, count=1)
    if not n:
        raise ValueError(f"{name!r}: a metric-valued field is named for µm (``…_um``)")
    return key


def json_key(record, field: dataclasses.Field) -> str:
    """The JSON key of ``field`` of the dataclass ``record``: its name, or for a metric-valued field
    (:func:`in_metric_unit`) :func:`unit_key` of the record's ``unit``."""
    return unit_key(field.name, record.unit) if field.metadata.get("in_metric_unit") else field.name


def json_fields(record, names=None) -> dict:
    """The fields of the dataclass ``record`` that its JSON holds, ``{json key: value}`` (values as
    they are): every field but a nested record's :func:`unit_field`, metric values keyed by the
    unit (:func:`json_key`); with ``names`` those fields only, in that order. The start of a
    ``to_dict`` that leaves some out or renames some."""
    fields = {f.name: f for f in dataclasses.fields(record) if f.metadata.get("in_json", True)}
    return {json_key(record, fields[n]): getattr(record, n) for n in (fields if names is None else names)}


def to_json(x):
    """``x`` as JSON-able data (module docstring)."""
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return {k: to_json(v) for k, v in json_fields(x).items()}
    if isinstance(x, dict):
        return {str(k): to_json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [to_json(v) for v in x]
    if isinstance(x, np.ndarray) or (hasattr(x, "shape") and hasattr(x, "dtype") and not np.isscalar(x)):
        return to_json(np.asarray(x).tolist())
    if isinstance(x, (bool, np.bool_)):
        return bool(x)
    if isinstance(x, (int, np.integer)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        return float(x) if math.isfinite(float(x)) else None
    return x


class Result:
    """Mixin of the typed results: :meth:`to_dict` is :func:`to_json` of the fields."""

    def to_dict(self) -> dict:
        """JSON-able data, keys as the fields (:mod:`jaxbelt.infra.results`)."""
        return to_json(self)
