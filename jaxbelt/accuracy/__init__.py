"""Accuracy on demand: how far a run is from the converged solution, and the cheapest run that
meets an accuracy.

* :mod:`jaxbelt.accuracy.estimate` — :func:`estimate_error`, the discretisation error of a run
  by Richardson extrapolation in each direction of the grid (``n_xi``, ``n_eta``, ``dt``);
* :mod:`jaxbelt.accuracy.choice` — :func:`choose_grid`, the cheapest grid (and, where it
  suffices, the 1D model and float32) whose verified estimate meets an accuracy.
"""

from .choice import (PRECISIONS, QUANTITIES, REFINEMENTS, AccuracyError, GridChoice, ModelCheck, asked_value,
                     choose_grid, one_d_counterpart, precision_scope, window_difference_um)
from .estimate import (DIRECTIONS, LADDERS, ORDER_RANGE, SAFETY_FACTOR, DirectionError, DiscretisationError, Grid,
                       TracerRun, admissible, at_times, estimate_error, observed_order, refine, richardson_limit,
                       scene_grid, tracer_run)

__all__ = [
    "AccuracyError", "DIRECTIONS", "DirectionError", "DiscretisationError", "Grid", "GridChoice", "LADDERS",
    "ModelCheck", "ORDER_RANGE", "PRECISIONS", "QUANTITIES", "REFINEMENTS", "SAFETY_FACTOR", "TracerRun",
    "admissible", "asked_value", "at_times", "choose_grid", "estimate_error", "observed_order", "one_d_counterpart",
    "precision_scope", "refine", "richardson_limit", "scene_grid", "tracer_run", "window_difference_um",
]
