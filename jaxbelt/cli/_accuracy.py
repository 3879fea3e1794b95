"""``--accuracy-um`` and ``--error-estimate``, shared by ``simulate`` and the design commands:
the options, their checks (one line, exit 2) and their text output (:mod:`jaxbelt.accuracy`)."""

from __future__ import annotations

import math
import sys

from ..accuracy import AccuracyError, choose_grid, estimate_error
from ..accuracy.choice import DEFAULT_MAX_COST_S
from ._common import UsageError


def add_accuracy_arguments(p, estimate: bool = True):
    p.add_argument("--accuracy-um", type=float, default=None, metavar="X",
                   help="run on the cheapest grid (n_xi, n_eta, dt) whose estimated discretisation error is at most "
                        "X µm, verified by its own estimate (default: the scene's [solver] accuracy_um, else the "
                        "scene's grid)")
    p.add_argument("--max-cost-s", type=float, default=DEFAULT_MAX_COST_S, metavar="S",
                   help="with --accuracy-um: refuse, before it runs, a grid whose run and verification are "
                        f"predicted to take longer than S s (default {DEFAULT_MAX_COST_S:g}; the time spent choosing counts)")
    if estimate:
        p.add_argument("--error-estimate", action="store_true",
                       help="also estimate the run's discretisation error (Richardson in n_xi, n_eta and dt; "
                            "several more runs)")


def accuracy_asked(args, scene):
    """``--accuracy-um``, else the scene's ``[solver] accuracy_um``, else ``None``; checked."""
    x = getattr(args, "accuracy_um", None)
    if x is None:
        return scene.solver.accuracy_um
    if not (math.isfinite(x) and x > 0):
        raise UsageError(f"--accuracy-um = {x}: must be a positive number of µm")
    return x


def _progress(args):
    if getattr(args, "progress", False) or (not getattr(args, "json", False) and sys.stderr.isatty()):
        return lambda line: print(f"jaxbelt: accuracy: {line}", file=sys.stderr, flush=True)
    return None


def choose_accuracy(args, scene, quantities=None, t_from: float = 0.0, **allow):
    """The :class:`jaxbelt.accuracy.GridChoice` for the accuracy asked (the error taken over the
    output times from ``t_from`` on; ``allow``: ``allow_1d``, ``allow_float32``, ``allow_reuse`` of
    :func:`~jaxbelt.accuracy.choose_grid`), or ``None``."""
    x = accuracy_asked(args, scene)
    if x is None:
        return None
    budget = getattr(args, "max_cost_s", DEFAULT_MAX_COST_S)
    if not (math.isfinite(budget) and budget > 0):
        raise UsageError(f"--max-cost-s = {budget}: must be a positive number of seconds")
    try:
        return choose_grid(scene, x, quantities, t_from=t_from, progress=_progress(args), max_cost_s=budget, **allow)
    except AccuracyError as e:
        raise UsageError(str(e)) from None


def error_estimate(args, scene) -> dict:
    """``discretisation_error_um`` of the scene's run."""
    return estimate_error(scene, progress=_progress(args), t_from=getattr(args, "accuracy_from", 0.0)).to_dict()


def print_accuracy(s: dict):
    """Text lines for ``chosen`` and ``discretisation_error_um`` of a summary, where present."""
    c = s.get("chosen")
    if c is not None:
        print(f"  chosen for {c['accuracy_um']:g} µm: n_xi = {c['n_xi']}, n_eta = {c['n_eta']}, dt = {c['dt_s']:g} s, "
              f"{c['solver']}, {c['model']} model, {c['precision']}; estimate {c['estimate_um']:.3g} µm, "
              f"{c['cost_s']:.3g} s a run")
        for line in c["automatic"]:
            print(f"    automatic: {line}")
    e = s.get("discretisation_error_um")
    if e is not None:
        lat = "" if e["lateral"] is None else f", lateral {e['lateral']:.3g} µm"
        orders = ", ".join(f"{d} {'-' if p is None else f'{p:.2f}'}" for d, p in e["orders"].items())
        print(f"  discretisation error (estimate): longitudinal {e['longitudinal']:.3g} µm{lat}; dominant "
              f"{e['dominant']}; observed orders {orders}; the estimate cost {e['cost_runs']:.1f} runs")
        for line in estimate_caveats(s):
            print(f"  warning: {line}")


ROUNDOFF_UM = 1e-6  # an error estimate below this is round-off of a machine at rest in its frame


def estimate_caveats(s: dict) -> list[str]:
    """What makes a summary's error estimate doubtful, in words: an observed order held at a bound
    of its admissible range (the differences do not show the asymptotic rate), and an estimate
    larger than the signal it is the error of (the grid resolves too little of it). Both are left
    unsaid where the estimate is at round-off (below :data:`ROUNDOFF_UM`): there is nothing to resolve."""
    e = s.get("discretisation_error_um")
    if e is None or max(e.get("longitudinal") or 0.0, e.get("lateral") or 0.0) < ROUNDOFF_UM:
        return []
    out = []
    for d, x in e.get("directions", {}).items():
        if x.get("order_clamped"):
            order = "-" if x.get("order") is None else f"{x['order']:.2g}"
            out.append(f"the observed order in {d} sits at a bound of its range ({order}): the runs are not in "
                       "the asymptotic range, and the estimate is a rough one")
    for name, key in (("longitudinal", "tracer_u_max_abs_um"), ("lateral", "tracer_v_max_abs_um")):
        err, signal = e.get(name), s.get(key)
        if err is not None and signal is not None and err > signal:
            out.append(f"the {name} error estimate ({err:.3g} µm) exceeds the {name} signal itself "
                       f"(max |tracer| {signal:.3g} µm): the grid resolves too little of it; refine it")
    return out
