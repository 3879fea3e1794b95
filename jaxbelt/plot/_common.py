"""Shared pieces of the figure functions: matplotlib (imported lazily), writing or returning a figure, a panel's axes."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

from ..infra.results import json_fields, to_json


def pyplot():
    """``matplotlib.pyplot``, imported at the first figure."""
    import matplotlib.pyplot as plt  # the user's / environment's backend (see the module docstring)

    return plt


def finish_figure(fig, path, dpi=120):
    """Write ``fig`` to ``path`` and close it (returns ``path``), or return the open figure when
    ``path`` is ``None``."""
    if path is None:
        return fig
    fig.savefig(path, dpi=dpi)
    pyplot().close(fig)
    return path


def axes_or_new(ax, figsize=(6, 4.5)):
    """``ax`` or a new single-panel figure; returns ``(fig or None, ax)``."""
    if ax is not None:
        return None, ax
    plt = pyplot()
    fig, ax = plt.subplots(figsize=figsize, constrained_layout=True)
    return fig, ax


def result_record(result) -> Mapping:
    """A result's entries by their JSON keys: a mapping (a result's ``to_dict()``) as it is; a
    dataclass (the results of :mod:`jaxbelt.design`) as every field, keyed as in JSON
    (:func:`jaxbelt.infra.results.json_key`: metric values keyed by the record's unit), ``yield_``
    under ``"yield"``."""
    if isinstance(result, Mapping):
        return result
    if dataclasses.is_dataclass(result):  # nested records as JSON-able data, as in their to_dict()
        return {("yield" if k == "yield_" else k): to_json(v) for k, v in json_fields(result).items()}
    raise TypeError(f"expected a result of jaxbelt.design or a mapping, got {type(result).__name__}")
