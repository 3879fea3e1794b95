"""Whether a steady state is one the machine can hold (:func:`check_steady`), and the actuator
jitter around it that steady operation leaves out (:func:`actuator_jitter`)."""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from ..model import BeltModel
from ..run_checks import belt_speed
from ..timeloop import SaveAt, simulate
from .fixed_point import NoSteadyStateError, SteadyState

JITTER_TURNS = 2.0  # belt turns of the time-stepped run that measures the actuator jitter


def check_steady(s, model: BeltModel, what: str = "the aligned machine"):
    """:class:`NoSteadyStateError` unless ``s`` (concrete) is a steady operation the
    machine can hold: converged, its actuators within their range, the belt on its rollers."""
    if not bool(s.converged) or not np.all(np.isfinite(np.asarray(s.tracer_u))):
        raise NoSteadyStateError(f"no steady operation of {what}: the fixed-point iteration did not converge "
                                 f"(residual {float(s.residual):.3g} µm after {int(s.newton_steps)} Newton steps)")
    if s.angle is not None:
        need, limit = np.abs(np.asarray(s.angle)), np.asarray(model.control.limit)
        for label, a, lim in zip(model.control.labels, need, limit):
            if a > lim:
                raise NoSteadyStateError(f"no steady operation of {what}: the loop on {label} needs {a * 1e3:.4g} mrad "
                                         f"to hold the belt, beyond its ±{lim * 1e3:.4g} mrad range")
    if s.edge_margin is not None and np.min(np.asarray(s.edge_margin)) < 0:
        raise NoSteadyStateError(f"no steady operation of {what}: the belt edge runs off a roller "
                                 f"({-np.min(np.asarray(s.edge_margin)) * 1e3:.3g} mm beyond its face)")


def actuator_jitter(model: BeltModel, solver, dt, s: SteadyState, turns: float = JITTER_TURNS):
    """The aligned machine's actuator jitter around its steady angle, mrad (n_c,): the largest
    ``|angle − steady angle|`` of a time-stepped run of ``model`` (sensor noise and edge profile
    on) from its steady state ``s`` over ``turns`` belt turns. A loop whose steady state is not
    stable shows here: the deviation growing from the first turn to the last is named
    (:class:`NoSteadyStateError`)."""
    loops = model.control
    n = max(2, int(np.ceil(turns * float(loops.loop_length) / belt_speed(model) / float(dt))))
    y0 = dataclasses.replace(s.state, control=dataclasses.replace(s.state.control, travel=jnp.zeros((), dt.dtype)))
    _, tr = simulate(model, solver, n_steps=n, dt=dt, y0=y0, saveat=SaveAt(), check=False)
    dev = np.abs(np.asarray(tr.control_u) - np.asarray(s.angle)[None])
    if not np.all(np.isfinite(dev)):
        raise NoSteadyStateError("no steady operation: the aligned machine's run from its steady state diverged "
                                 "(an unstable loop)")
    half = n // 2
    first, last = dev[:half].max(axis=0), dev[half:].max(axis=0)
    if np.any((last > 4 * first) & (last > 0.05 * np.asarray(loops.limit))):
        raise NoSteadyStateError(f"no steady operation: the steady state is unstable (actuator deviation grows from "
                                 f"{first.max() * 1e3:.3g} to {last.max() * 1e3:.3g} mrad over {turns:g} belt turns: "
                                 "a growing loop mode; lower the gains)")
    return jnp.asarray(dev.max(axis=0) * 1e3, dt.dtype)
