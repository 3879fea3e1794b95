"""Figures (matplotlib, imported at the first figure; of jaxbelt only the command line imports this module).

Displacements are drawn in mm and times in s, as in the source's figures.

The functions that draw a whole figure (:func:`plot_run`, :func:`plot_scene`,
:func:`plot_reduction`, :func:`plot_sensitivity`, :func:`plot_tolerance_box`, :func:`plot_yield`)
write a PNG and return its path when given ``path``; with ``path=None`` they return the open
:class:`matplotlib.figure.Figure` (shown inline in Jupyter). The panel functions take an ``ax``.
This module never selects a matplotlib backend: a notebook keeps its inline backend; the command
line sets ``MPLBACKEND=Agg`` (unless the user set one) before matplotlib is imported.

The functions live in submodules by what they draw (:mod:`~jaxbelt.plot.fields`, :mod:`~jaxbelt.plot.runs`,
:mod:`~jaxbelt.plot.reduction`, :mod:`~jaxbelt.plot.design`, :mod:`~jaxbelt.plot.belt3d`); all are imported here.
"""

from .fields import tracer_styles, belt_segments, tracer_positions, tracer_labels, select_times, field_values, plot_fields
from .runs import plot_run, plot_scene, plot_steering
from .reduction import plot_singular_values, plot_dmd_eigenvalues, plot_rmse_over_time, plot_reduction
from .design import plot_sensitivity, plot_tolerance_box, plot_yield
from .belt3d import belt_geometry_3d, belt_surface_3d, plot_belt_3d

__all__ = [
    "tracer_styles",
    "plot_run",
    "plot_steering",
    "plot_scene",
    "plot_singular_values",
    "plot_dmd_eigenvalues",
    "plot_rmse_over_time",
    "plot_reduction",
    "plot_sensitivity",
    "plot_tolerance_box",
    "plot_yield",
    "belt_segments",
    "tracer_positions",
    "tracer_labels",
    "select_times",
    "field_values",
    "plot_fields",
    "belt_geometry_3d",
    "belt_surface_3d",
    "plot_belt_3d",
]
