"""The one serialisation convention of jaxbelt's typed results.

Every result is a frozen dataclass whose fields carry their unit in their name (``_um``, ``_mrad``,
``_s``, ``_mm_s_per_mrad``: SI with a prefix, micrometres wherever a belt position is reported),
holds typed values (nested results are dataclasses, not dicts), and turns into JSON-able data by
:func:`to_json`: nested dataclasses become objects, arrays and tuples lists, numpy scalars Python
numbers, and a non-finite float ``null`` (JSON has no ``inf`` or ``nan``; a margin that does not
exist, a run that diverged). A result that presents itself differently in JSON (a renamed key,
rows built from parallel arrays) says so in its own ``to_dict``, which still ends in
:func:`to_json`.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np


def to_json(x):
    """``x`` as JSON-able data (module docstring)."""
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return {f.name: to_json(getattr(x, f.name)) for f in dataclasses.fields(x)}
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
