"""The steering plant from the model: coefficient, disturbance, hold angle, walk sensitivity,
the identified transfer function, and the P loop's stability boundary from closed-loop runs.

Everything is measured on the full model with the loop *open* (gains 0, so the actuator angle
``u ≡ 0``) unless a run says otherwise. A *step of the actuator* is applied through the loop's
own actuator path: the controller is saturated (``k_p = 1``, a setpoint 1 m away, the range set
to the step), so the angle ``u = a`` is held from the first step on, through the actuator lag
(the rate limit is lifted: the identified plant is the linear one).

**Walk rates** come from the open-loop machine's *steady walk* (:func:`jaxbelt.steady.steady_walk`):
the fixed point of its one-step map up to a uniform lateral drift, whose rate is solved for — the
walk once every transient has died out, with no run length or fitting window to choose. The
coefficient and every misalignment's walk sensitivity are its derivatives (implicit function
theorem, :func:`steady_walk_jacobian`), the disturbance the scene's walk minus the aligned
machine's. The step response that the plant is identified from is still a time-stepped run (its
transient is the point).

**The sampled loop's timing.** The controller reads the sensor at the state of ``t_k`` and its
angle acts through the step ``t_k → t_{k+1}``, held for the sample period ``T_s`` (zero-order
hold). The open-loop step response already holds the one-step lag (a step of the angle at
``t = 0`` first shows at ``t_1``), so the closed P loop is exactly the discrete loop of the
step-response samples, ``u_k = −k_p y_k``: its margin is :func:`response_gain_margin`, with no
fitted form in between. The continuous identified plant needs the hold's delay ``T_s / 2``
added (:func:`sampling_delay`, ``margins(plant, ..., sample_delay=…)``) to describe
that loop.

Library functions: :func:`steering_report` (``jaxbelt steering``), :func:`stability_boundary`,
:func:`response_gain_margin`; the plant's identification is :func:`jaxbelt.steering.plant.identify_plant`,
the discrete loop :class:`jaxbelt.steering.response.DiscreteLoop`.
"""

from __future__ import annotations

import dataclasses
import time
import warnings

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from ..control import samples_per_update, walk_rate
from ..infra.results import Result
from ..misalignment import dof_directions, parameter_space
from ..steady import check_steady, steady_with_tangents
from ..run_checks import belt_speed
from ..timeloop import RunOptions
from .plant import SteeringPlant, identify_plant
from .response import DiscreteLoop, open_loop_response, open_loops, run_batch
from .transfer import margins

STEP_MRAD = 0.1  # default actuator step, mrad (linear range)


class SteeringWarning(UserWarning):
    """A steering loop cannot hold the belt within its range."""


def _require_loop(model, loop):
    if model.control is None or not model.control.n_loops:
        raise ValueError("the scene has no [[control]] steering loop")
    if not 0 <= loop < model.control.n_loops:
        raise ValueError(f"loop = {loop}: the scene has {model.control.n_loops} steering loop(s)")


# ------------------------------------------------------------------------------ the discrete loop


def sampling_delay(loops, dt, loop: int = 0) -> float:
    """The sampled loop's own delay beyond the step response, s: half the sample period
    ``T_s = n_s Δt`` (the zero-order hold, module docstring)."""
    return 0.5 * float(samples_per_update(loops, dt)[loop]) * float(dt)


def response_gain_margin(response, gain, dt, sample_steps: int = 1):
    """``(gain_margin, omega_pc)`` of the sampled P loop on the step response itself
    (:class:`~jaxbelt.steering.response.DiscreteLoop`, the loop's sign folded in; rad/m,
    ``inf``/``nan`` without a crossing)."""
    gm, _, w_pc, _ = margins(DiscreteLoop(np.asarray(response, float), float(gain), float(dt), int(sample_steps)), 1.0)
    return gm, w_pc


# ------------------------------------------------------------------------------ the report


@dataclasses.dataclass(frozen=True)
class StepResponse(Result):
    """The model's open-loop response to a step of the actuator angle at ``t = 0``
    (:func:`~jaxbelt.steering.response.open_loop_response`). **Fields:** ``t_s`` (n,) the record
    times; ``sensor_um_per_mrad`` (n,) the belt's lateral displacement at the sensor per mrad of
    the step."""

    t_s: np.ndarray
    sensor_um_per_mrad: np.ndarray


@dataclasses.dataclass(frozen=True)
class SteeringReport(Result):
    """The plant of one steering loop, measured on the model with the loop open.

    **Fields:** ``loop`` the loop's label ``"roller/axis"``; ``coefficient_mm_s_per_mrad`` the
    steady walk rate at the sensor per mrad of actuator angle (stepped run minus unstepped);
    ``disturbance_mm_s`` the walk rate the scene's own misalignments cause at the sensor, minus
    the aligned machine's; ``hold_angle_mrad`` ``−disturbance / coefficient``, the angle that stops
    the walk; ``limit_mrad`` the loop's range; ``saturated`` whether the hold angle is beyond it
    (then a :class:`SteeringWarning` names the loop and the angle); ``walk_sensitivity``
    ``{roller: WalkSensitivity}`` (:class:`WalkSensitivity`) the walk rate per unit of each misalignment component at the scene's misalignment (derivatives
    of the open-loop steady walk; structurally zero components, such as the drive rotation about
    z, are 0), or ``None`` when not asked for; ``plant`` the identified transfer function
    (:class:`~jaxbelt.steering.plant.SteeringPlant`: SI, m/s per rad, s, m per rad; ``None`` when not
    identified);
    ``plant_fit_error`` its largest deviation from the model's step response as a fraction of
    the response's range; ``sample_delay_s`` the sampled loop's own delay ``T_s / 2``
    (:func:`sampling_delay`); ``plant_gain_margin`` the identified plant's P-loop gain margin with
    that delay (the stability boundary ``k_p``, mrad/mm) and ``plant_crossover_period_s`` its
    oscillation period; ``response_gain_margin`` and ``response_crossover_period_s`` the same of
    the discrete loop on the step response itself (:func:`response_gain_margin`, no fitted form);
    ``step_mrad`` the actuator step; ``t_end_s``, ``dt_s`` the runs; ``step_response`` the
    model's open-loop response to the step (:class:`StepResponse`); ``belt_speed_m_s``, ``loop_time_s`` the transit time;
    ``elapsed_s`` the wall time.
    """

    loop: str
    coefficient_mm_s_per_mrad: float
    disturbance_mm_s: float
    hold_angle_mrad: float
    limit_mrad: float
    saturated: bool
    walk_sensitivity: dict[str, WalkSensitivity] | None
    plant: SteeringPlant | None
    plant_fit_error: float
    sample_delay_s: float
    plant_gain_margin: float
    plant_crossover_period_s: float
    response_gain_margin: float
    response_crossover_period_s: float
    step_mrad: float
    t_end_s: float
    dt_s: float
    step_response: StepResponse
    belt_speed_m_s: float
    loop_time_s: float
    elapsed_s: float


def _period_of(w):
    return float(2 * np.pi / w) if np.isfinite(w) else float("nan")


def steady_walk_jacobian(model, options: RunOptions, dofs) -> tuple[np.ndarray, float]:
    """The open-loop steady walk rate's derivatives (m/s per m or rad) with respect to the roller
    DOFs ``dofs`` (flat indices of ``chi_static``), at the model's own misalignment: the steady walk
    and one tangent solve per DOF (implicit function theorem) in one program
    (:func:`jaxbelt.steady.steady_with_tangents`). **Returns:** ``(derivatives, the walk rate
    itself)``."""
    opened, dt = model.replace(control=None), jnp.asarray(options.dt, model.ell.dtype)
    s, J = steady_with_tangents(opened, options.solver, dt=dt, directions=dof_directions(opened, dofs))
    check_steady(s, opened, "the open-loop machine")
    return np.asarray(J[-1]), float(s.walk_rate)


@dataclasses.dataclass(frozen=True)
class WalkSensitivity(Result):
    """The open-loop walk rate's derivatives with respect to one roller's misalignment components
    (:func:`walk_sensitivity`). **Fields:** ``translation_mm_s_per_mm`` ``(x, y, z)``;
    ``rotation_mm_s_per_mrad`` ``(x, y, z)``."""

    translation_mm_s_per_mm: tuple
    rotation_mm_s_per_mrad: tuple


@dataclasses.dataclass(frozen=True)
class LoopGrowth(Result):
    """One closed-loop run of :func:`stability_boundary`. **Fields:** ``kp_mrad_per_mm`` its
    proportional gain; ``growth`` the sensor oscillation's envelope over the last third of the run
    against the middle third (> 1: growing)."""

    kp_mrad_per_mm: float
    growth: float


def walk_sensitivity(model, options: RunOptions, loop: int = 0, jacobian=None) -> dict[str, WalkSensitivity]:
    """``{roller: WalkSensitivity}``: the derivatives of the open-loop steady walk rate w.r.t.
    every misalignment component that can vary, at the model's own misalignment
    (:func:`steady_walk_jacobian`; ``jacobian`` the derivatives already taken in the order of the
    components)."""
    _require_loop(model, loop)
    space = parameter_space(model)
    g = steady_walk_jacobian(model, options, space.chi_index)[0] if jacobian is None else np.asarray(jacobian)
    per = space.per_roller(g)  # m/s per m = mm/s per mm; m/s per rad = mm/s per mrad
    return {name: WalkSensitivity(tuple(float(x) for x in d["translation"]), tuple(float(x) for x in d["rotation"]))
            for name, d in per.items()}


def steering_report(model, options: RunOptions, *, loop: int = 0, step_mrad: float = STEP_MRAD,
                    sensitivity: bool = True, identify: bool = True) -> SteeringReport:
    """The plant of loop ``loop`` (:class:`SteeringReport`; module docstring for the method).

    The walk rates from steady walks (module docstring): the scene's with its derivatives (the
    coefficient and the walk sensitivity) in one program, the aligned machine's beside it. The
    measured step response (:func:`~jaxbelt.steering.response.open_loop_response`: two open-loop
    runs in one vmapped batch, the scene's machine and the same with the actuator stepped by
    ``step_mrad``, ``options.n_steps`` steps of ``options.dt``) gives the plant by
    :func:`identify_plant` (``identify=False``: skipped, the plant
    fields ``None``/NaN). A hold angle beyond the loop's range sets ``saturated`` and warns
    (:class:`SteeringWarning`).
    """
    _require_loop(model, loop)
    start = time.perf_counter()
    a = step_mrad * 1e-3
    opened = open_loops(model)
    aligned = opened.replace(chi_static=jnp.zeros_like(model.chi_static))
    step = open_loop_response(model, options, amplitude=a, loop=loop)
    t, resp = step.t, step.step  # m per rad
    space = parameter_space(model)
    dofs = list(space.chi_index) + [model.control.actuator_dof[loop]]
    J, walk = steady_walk_jacobian(opened, options, dofs)
    # the aligned machine's walk by the same program, without tangents
    opened_aligned = aligned.replace(control=None)
    s0, _ = steady_with_tangents(opened_aligned, options.solver, dt=jnp.asarray(options.dt, model.ell.dtype),
                                 directions=dof_directions(opened_aligned, dofs), n_tangents=0)
    check_steady(s0, opened_aligned, "the aligned open-loop machine")
    walk_aligned = float(s0.walk_rate)
    disturbance = (walk - walk_aligned) * 1e3  # mm/s
    coeff = float(J[-1])  # m/s per rad = mm/s per mrad
    hold = -disturbance / coeff
    limit = float(model.control.limit[loop]) * 1e3
    label = model.control.labels[loop]
    saturated = bool(abs(hold) > limit)
    if saturated:
        warnings.warn(f"steering loop {label}: holding the belt needs {hold:.4g} mrad, beyond the range "
                      f"±{limit:.4g} mrad: the loop saturates and the belt walks", SteeringWarning, stacklevel=2)
    V = belt_speed(model)
    loop_time = float(model.control.loop_length) / V
    n_s = int(samples_per_update(model.control, options.dt)[loop])
    delay = sampling_delay(model.control, options.dt, loop)
    plant, err, gm, w_pc = None, float("nan"), float("nan"), float("nan")
    if identify:
        plant, err = identify_plant(t, resp, coeff, loop_time)  # mm/s per mrad = m/s per rad
        gm, _, w_pc, _ = margins(plant, 1.0, sample_delay=delay)
    rgm, rw_pc = response_gain_margin(resp, coeff, options.dt, n_s)
    sens = walk_sensitivity(model, options, loop, J[:-1]) if sensitivity else None
    return SteeringReport(
        loop=label, coefficient_mm_s_per_mrad=coeff, disturbance_mm_s=disturbance, hold_angle_mrad=float(hold),
        limit_mrad=limit, saturated=saturated, walk_sensitivity=sens,
        plant=plant, plant_fit_error=err,
        sample_delay_s=delay, plant_gain_margin=float(gm), plant_crossover_period_s=_period_of(w_pc),
        response_gain_margin=rgm, response_crossover_period_s=_period_of(rw_pc),
        step_mrad=float(step_mrad), t_end_s=float(t[-1]), dt_s=float(options.dt),
        step_response=StepResponse(t_s=np.asarray(t, float), sensor_um_per_mrad=np.asarray(resp, float) * 1e3),
        belt_speed_m_s=V, loop_time_s=loop_time, elapsed_s=time.perf_counter() - start)


# ------------------------------------------------------------------------------ the P loop's boundary


@dataclasses.dataclass(frozen=True)
class StabilityBoundary(Result):
    """The P-only loop's stability boundary from closed-loop runs of the model.

    **Fields:** ``loop`` the label; ``kp_mrad_per_mm`` the boundary (midpoint of the last
    bracket); ``bracket`` ``(stable, unstable)`` k_p, mrad/mm; ``growth`` every run's gain and envelope
    growth (:class:`LoopGrowth`), in increasing gain; ``period_s`` the oscillation period at the unstable end (zero crossings);
    ``t_end_s``, ``dt_s`` the runs; ``runs`` how many; ``elapsed_s``."""

    loop: str
    kp_mrad_per_mm: float
    bracket: tuple
    growth: tuple[LoopGrowth, ...]
    period_s: float
    t_end_s: float
    dt_s: float
    runs: int
    elapsed_s: float



def _detrended(t, v):
    """``v`` (…, n) less its least-squares line over ``t`` (:func:`jaxbelt.control.walk_rate`'s slope)."""
    slope = np.asarray(walk_rate(t, v, (t[0], t[-1])))
    return v - v.mean(axis=-1, keepdims=True) - slope[..., None] * (t - t.mean())


def _growth(t, v):
    """Envelope growth of the oscillation (detrended by a line over the last two thirds): the RMS
    over the last third against the middle third, per row of ``v``."""
    n = v.shape[-1]
    a, b = n // 3, 2 * n // 3
    r = _detrended(t[a:], v[:, a:])
    mid, last = r[:, : b - a], r[:, b - a:]
    return np.sqrt((last**2).mean(axis=1)) / np.maximum(np.sqrt((mid**2).mean(axis=1)), 1e-300)


def _period(t, v):
    r = _detrended(t, v)
    zc = t[1:][np.diff(np.sign(r)) != 0]
    return float(2 * np.mean(np.diff(zc[len(zc) // 3:]))) if len(zc) > 3 else float("nan")


def stability_boundary(model, options: RunOptions, kp_low: float, kp_high: float, *, loop: int = 0,
                       batch: int = 5, rounds: int = 3) -> StabilityBoundary:
    """The P-only stability boundary of loop ``loop`` (``k_i = k_d = 0``), in mrad/mm, by a batched
    bisection: each round runs ``batch`` closed-loop runs (vmapped) on a grid inside the bracket
    ``[kp_low, kp_high]`` (stable, unstable) and keeps the sub-interval where the oscillation
    envelope starts to grow (:func:`_growth` > 1). The scene's own misalignment excites the loop;
    its sensor noise and edge profile are removed. Runs ``options.n_steps`` steps each."""
    _require_loop(model, loop)
    start = time.perf_counter()
    c = model.control
    quiet = model.replace(control=eqx.tree_at(lambda s: (s.noise, s.profile_amplitude, s.limit, s.rate_limit), c,
                                              (0 * c.noise, 0 * c.profile_amplitude, jnp.full_like(c.limit, 1.0),
                                               jnp.full_like(c.rate_limit, jnp.inf))))
    lo, hi = float(kp_low), float(kp_high)
    growth, runs, period = {}, 0, float("nan")
    for _ in range(rounds):
        kps = np.linspace(lo, hi, batch + 2)[1:-1]
        models = [quiet.replace(control=quiet.control.with_gains(jnp.zeros_like(c.kp).at[loop].set(k), 0.0, 0.0))
                  for k in kps]
        t, v, _, _ = run_batch(models, options, loop)
        runs += len(kps)
        g = _growth(t, v)
        growth.update({float(k): float(x) for k, x in zip(kps, g)})
        unstable = g > 1.0
        for k, u, vv in zip(kps, unstable, v):
            if u:
                hi = float(k)
                period = _period(t[len(t) // 2:], vv[len(t) // 2:])
                break
            lo = float(k)
    growth = tuple(LoopGrowth(k, growth[k]) for k in sorted(growth))
    return StabilityBoundary(loop=c.labels[loop], kp_mrad_per_mm=0.5 * (lo + hi), bracket=(lo, hi), growth=growth,
                             period_s=period, t_end_s=float(options.n_steps * options.dt), dt_s=float(options.dt),
                             runs=runs, elapsed_s=time.perf_counter() - start)
