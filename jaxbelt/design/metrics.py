"""Belt-position metrics of a tolerance study, in µm, relative to the aligned machine.

Every metric compares a misaligned run with the *aligned* run of the same scene (every
misalignment zero, :func:`jaxbelt.misalignment.aligned`), tracer by tracer and step by step,
so the static stretching of the belt by its pre-tension and drive does not count. With
``d_u``, ``d_v`` (steps, tracers) the longitudinal and lateral tracer deviations in µm, ``k``
the evaluation step (``t_eval``) and ``W`` the evaluation window, the last ``window`` steps of
``[0, t_eval]`` (10 % of the run; 20 % on a steered machine):

| metric | open loop: response ``r`` | steered machine: response ``r`` | aggregate |
|---|---|---|---|
| ``lateral_rms`` | ``d_v[k]`` (n_tr,) | ``d_v[W]`` flattened | RMS |
| ``lateral_max`` | ``d_v[k]`` | ``d_v[W]`` flattened | max-abs |
| ``longitudinal_rms`` | ``d_u[k]`` | ``d_u[W]`` flattened | RMS |
| ``longitudinal_max`` | ``d_u[k]`` | ``d_u[W]`` flattened | max-abs |
| ``lateral_peak`` | ``d_v[W]`` flattened | the same | max-abs |
| ``walk_rate`` | µm/s: least-squares slope of $\\bar d_v(t) = \\tfrac1n\\sum_i d_v(t, i)$ over the second half of ``[0, t_eval]`` (meaningful with ``lateral_transport = true``), (1,) | the same | max-abs |
| ``steering_max`` | — (needs a steering loop) | mrad: the actuator angles ``u[W]`` (n_c per step) themselves, flattened | max-abs |

*Steered machine* means a model with ``[[control]]`` steering loops (``model.control``): its
belt is held by the loop, so its metrics read the whole window of steady operation instead of
one instant, and the aligned reference is the aligned machine *with its loop closed*. The
sensor's noise and the belt edge's own profile enter both runs alike (the same seed): they
cancel in the deviations. ``steering_max`` is the only metric that is not a deviation: the
actuator's range is an absolute, so it is the largest actuator angle in the window (noise and
profile included), in mrad. :func:`evaluate` also reports whether the actuator *saturated*: an
angle within 0.1 % of its range limit in the window (``SATURATION_FRACTION``), which is where the
clipped command holds it (without an actuator lag it sits exactly on the limit).

The *response* ``r(θ)`` is the vector whose aggregate is the metric; it is nearly linear in the
misalignments — on a steered machine too, as long as its actuator does not saturate (the PI
law is linear until it clips) — which is what the tolerance box and FORM use
(``metric = agg(r)``). ``lateral_peak`` has a smooth version for gradients, the log-sum-exp soft
maximum $\\tau \\log \\sum e^{|r|/\\tau}$ (``smooth=True``, ``τ = 0.05`` µm by default: it exceeds the
hard maximum by at most ``τ log(len r)``).

**Steady operation** (``make_study(..., steady=True)``):
instead of a window of a time-stepped run, the study judges the settled machine, the fixed point of
its one-period map (:func:`jaxbelt.steady.steady_state`, noise and edge profile left out). Every
history then has one row — the steady state — so the table above applies with ``k = W = 0``: the
lateral and longitudinal deviation of every tracer from the aligned machine's steady state, and
the actuator's steady angle. ``steering_max``'s response is that angle widened by the aligned
machine's own actuator jitter ``j`` (sensor noise and edge waviness, measured once by a
time-stepped run from the aligned steady state over :data:`jaxbelt.steady.JITTER_TURNS` belt turns): the pair
``(a + j, a − j)``, whose max-abs is ``|a| + j``, still affine in the misalignments. A misalignment
the loop absorbs (the steering roller's own tilt about its actuated axis) then costs only actuator
range.

A study can carry *several limits* at once (``limits``: ``((metric, limit), ...)``, max-type
metrics only; :func:`with_limits`): its response is then every metric's response divided by its
limit, stacked, and carried on the scale of the first limit (the study's own metric's): its
metric is the largest ratio times that limit, and passes where it is within it — so the tolerance
box and the sweep see one constraint that holds all of them and read it in the study metric's
unit.
"""

from __future__ import annotations

import abc
import dataclasses
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np

from ..control import SATURATION_FRACTION, walk_rate

M_TO_UM = 1e6
RAD_TO_MRAD = 1e3
SMOOTH_TAU_UM = 0.05
OPEN_LOOP_WINDOW = 0.1  # fraction of [0, t_eval]: lateral_peak's window
CLOSED_LOOP_WINDOW = 0.2  # fraction of [0, t_eval]: the window of steady operation of a steered machine


@dataclasses.dataclass(frozen=True)
class Metric(abc.ABC):
    """One metric of the module table: its ``name``, how its response is aggregated
    (``aggregate``: ``"max"`` max-abs, ``"rms"``), the ``unit`` of its value, whether it needs a
    2D scene (``needs_2d``) and a steering loop (``needs_loop``), a one-line ``description``;
    :meth:`response` reads it from a run's deviations and :meth:`steps_read` says how many of a
    run's last steps that reads; ``quantities`` the tracer deviations (``"longitudinal"``,
    ``"lateral"``) whose discretisation error the metric carries — both by default (an actuator
    angle answers the lateral walk and the longitudinal registration alike); ``other_direction``
    the same measure in the other direction (``lateral_max`` ↔ ``longitudinal_max``: a 1D scene's
    default, and the further limit a steered machine holds),
    ``None`` where there is none; ``soft_maximum`` (class attribute) whether a gradient-based
    search (FORM's limit state) takes its maximum as the soft one of :func:`aggregate` — a maximum
    over every step of a window, whose peak jumps from step to step. A new metric is one subclass
    and one entry in :data:`METRICS`."""

    soft_maximum: ClassVar[bool] = False

    name: str
    aggregate: str
    unit: str
    needs_2d: bool
    needs_loop: bool
    description: str
    other_direction: str | None = None
    quantities: tuple[str, ...] = ("longitudinal", "lateral")

    @abc.abstractmethod
    def response(self, study, du, dv, angle):
        """The response vector ``r`` from the tracer deviations ``du``, ``dv`` (steps, n_tr) µm and
        the actuator angles ``angle`` (steps, n_c) mrad."""

    def steps_read(self, study) -> int:
        """How many of the last steps of a run :meth:`response` reads."""
        return study.window


def _window(study) -> slice:
    k = study.options.n_steps - 1
    return slice(k + 1 - study.window, k + 1)


@dataclasses.dataclass(frozen=True)
class TracerDeviation(Metric):
    """``lateral_*`` / ``longitudinal_*``: the tracers' deviation in one direction at ``t_eval``;
    on a steered machine over the window."""

    direction: str = "lateral"

    def __post_init__(self):
        object.__setattr__(self, "quantities", (self.direction,))  # its own direction only

    def response(self, study, du, dv, angle):
        d = dv if self.direction == "lateral" else du
        return d[_window(study)].reshape(-1) if study.steered else d[study.options.n_steps - 1]

    def steps_read(self, study):
        return study.window if study.steered else 1


@dataclasses.dataclass(frozen=True)
class LateralPeak(Metric):
    """``lateral_peak``: the lateral deviation over the window, every step of it."""

    soft_maximum: ClassVar[bool] = True
    quantities: tuple[str, ...] = ("lateral",)

    def response(self, study, du, dv, angle):
        return dv[_window(study)].reshape(-1)


@dataclasses.dataclass(frozen=True)
class WalkRate(Metric):
    """``walk_rate``: the least-squares slope of the mean lateral deviation over the second half
    of the run (:func:`jaxbelt.control.walk_rate`), µm/s."""

    quantities: tuple[str, ...] = ("lateral",)

    def response(self, study, du, dv, angle):
        t = (jnp.arange(study.options.n_steps) + 1.0) * study.options.dt
        return walk_rate(t, jnp.mean(dv, axis=1), (t[study.options.n_steps // 2], t[-1]))[None]

    def steps_read(self, study):
        return study.options.n_steps - study.options.n_steps // 2


@dataclasses.dataclass(frozen=True)
class SteeringMax(Metric):
    """``steering_max``: the steering actuators' angles over the window (in steady operation the
    steady angle widened by the aligned machine's jitter, module docstring), mrad."""

    def response(self, study, du, dv, angle):
        if angle is None:
            raise ValueError("steering_max: the run has no actuator angles (no steering loop)")
        if study.steady and study.jitter_mrad is not None:
            return jnp.concatenate([angle[0] + study.jitter_mrad, angle[0] - study.jitter_mrad])
        return angle[_window(study)].reshape(-1)


_STEERED = "(steered: over tracers and the window)"
METRICS = {m.name: m for m in (
    TracerDeviation("lateral_rms", "rms", "µm", True, False,
                    f"RMS over the tracers of the lateral deviation at t_eval {_STEERED}, µm", "longitudinal_rms",
                    direction="lateral"),
    TracerDeviation("lateral_max", "max", "µm", True, False,
                    f"largest |lateral deviation| over the tracers at t_eval {_STEERED}, µm", "longitudinal_max",
                    direction="lateral"),
    TracerDeviation("longitudinal_rms", "rms", "µm", False, False,
                    f"RMS over the tracers of the longitudinal deviation at t_eval {_STEERED}, µm", "lateral_rms",
                    direction="longitudinal"),
    TracerDeviation("longitudinal_max", "max", "µm", False, False,
                    f"largest |longitudinal deviation| over the tracers at t_eval {_STEERED}: registration, µm",
                    "lateral_max", direction="longitudinal"),
    LateralPeak("lateral_peak", "max", "µm", True, False, "largest |lateral deviation| over tracers and the window, µm",
                "longitudinal_max"),
    WalkRate("walk_rate", "max", "µm/s", True, False,
             "|slope| of the mean lateral deviation over the second half of the run, µm/s"),
    SteeringMax("steering_max", "max", "mrad", True, True,
                "largest |actuator angle| of the steering loops over the window, mrad"),
)}


def metric_unit(name: str) -> str:
    """The unit of a metric's value: ``"mrad"``, ``"µm/s"`` or ``"µm"``."""
    return METRICS[name].unit


def _single_response(study, name: str, du, dv, angle):
    return METRICS[name].response(study, du, dv, angle)


def response_from_deviation(study, du, dv, angle=None):
    """The metric's response vector ``r`` (see the module table) from the deviations and (for
    ``steering_max``) the actuator angles, mrad; with several limits the stacked ratios times the
    first limit (the study metric's: module docstring)."""
    if study.limit_names:
        return jnp.concatenate([_single_response(study, n, du, dv, angle) / study.limit_values[i]
                                for i, n in enumerate(study.limit_names)]) * study.limit_values[0]
    return _single_response(study, study.metric, du, dv, angle)


def aggregate(kind: str, r, smooth: bool = False, tau: float = SMOOTH_TAU_UM):
    """``max |r|`` (soft maximum with ``smooth``) or ``RMS(r)``; works on a trailing axis."""
    if kind == "rms":
        return jnp.sqrt(jnp.mean(r**2, axis=-1))
    if smooth:
        a = jnp.sqrt(r**2 + tau**2)
        return tau * jax.nn.logsumexp(a / tau, axis=-1)
    return jnp.max(jnp.abs(r), axis=-1)


def metric_from_deviation(study, du, dv, angle=None, smooth: bool = False):
    """The study's metric (its response aggregated, :func:`aggregate`) from a configuration's
    deviations and actuator angles: the one place a metric value is formed."""
    return aggregate(study.aggregate, response_from_deviation(study, du, dv, angle), smooth)


def on_limit_scale(values, limits) -> np.ndarray:
    """The measure of several limits at once (``limits`` ``((metric, limit), ...)``): each value
    (m, n_limits) over its limit, the largest, on the scale of the first limit (m,); without limits
    (``()``) the values as they are."""
    values = np.asarray(values)
    if not limits:
        return values
    lims = np.array([lim for _, lim in limits], float)
    return lims[0] * np.max(values / lims, axis=-1)


def limit_values_from_deviation(study, du, dv, angle):
    """Each limited metric's value (n_limits,) from the deviations and the actuator angles."""
    return jnp.stack([aggregate(METRICS[n].aggregate, _single_response(study, n, du, dv, angle)) for n in study.limit_names])


def aligned_values(study):
    """What :func:`metric_value` and (with several limits) :func:`limit_values` read on the aligned
    run, from the reference the study keeps (no run): ``(metric, limits (n_limits,) or None)``.
    The tracer deviations there are zero; a steering loop's angle is the reference's own."""
    du = jnp.zeros(study.ref_u.shape)
    dv = None if study.ref_v is None else jnp.zeros(study.ref_v.shape)
    angle = study.ref_angle
    metric = metric_from_deviation(study, du, dv, angle)
    return metric, limit_values_from_deviation(study, du, dv, angle) if study.limit_names else None


def response_sizes(study) -> list[int]:
    """The length of each limited metric's response block, in the order of ``study.limits``."""
    du = jnp.zeros(study.ref_u.shape)
    dv = None if study.ref_v is None else jnp.zeros(study.ref_v.shape)
    angle = None if study.model.control is None else jnp.zeros((study.options.n_steps, study.model.control.n_loops))
    return [int(_single_response(study, n, du, dv, angle).shape[0]) for n in study.limit_names]


def saturation(study, angle):
    """``(steering_mrad, saturated)`` from the actuator angles (n_steps, n_c) mrad: the largest
    |angle| in the window, and whether it reached ``SATURATION_FRACTION`` of its loop's range."""
    w = angle[study.options.n_steps - study.window:]
    if study.steady and study.jitter_mrad is not None:
        w = jnp.abs(w) + study.jitter_mrad
    limit = study.model.control.limit * RAD_TO_MRAD
    return jnp.max(jnp.abs(w)), jnp.any(jnp.abs(w) >= SATURATION_FRACTION * limit)
