"""Tuning of a steering loop: PI gains fitted by gradient descent through the whole closed-loop run.

**Objective.** The error is the belt's true lateral displacement at the sensor minus the setpoint,
``e(t) = v_sensor(t) − v_set`` (:attr:`jaxbelt.Trajectory.sensor_v`), over a closed-loop run of
the scene as it is: its misalignments (the disturbance), its edge profile and sensor noise enter
through the loop, and the objective measures what they leave on the belt. The first ``skip_s``
seconds (the start from the static state, which the gains do not change) are left out:

- ``ise``: ``∫ e² dt`` over ``[skip_s, t_end]``, µm²·s (sum over the steps × Δt);
- ``peak``: the log-sum-exp soft maximum of ``|e|``, ``β⁻¹ log Σ_k exp(β |e_k|)``, µm, with
  ``β = 5`` per µm: it exceeds ``max |e|`` by at most ``log(n) / β`` (1.5 µm for 2000 steps; less
  where one peak dominates) and its gradient is a weighted mean over the samples near the peak.

Both are ``jnp`` functions of the gains through the whole run (:func:`objective`), so
``jax.grad`` gives their exact gradient in ``(k_p, k_i)``.

**Constraints.** Gain margin ≥ 6 dB and phase margin ≥ 45° (``gm_min_db``, ``pm_min_deg``) of the
loop ``L = sign(k) G C`` on two descriptions of the plant:

- the identified plant (:class:`~jaxbelt.steering.plant.SteeringPlant` by
  :func:`jaxbelt.steering.plant.identify_plant`, with the loop's recirculation);
- the measured open-loop response of the full model
  (:class:`~jaxbelt.steering.response.MeasuredResponse`: the step response of the actuator
  angle, turned into ``G(iω)`` by a Fourier sum), unless
  ``constrain_response=False`` (a check that does not rest on the fit).

Both through the one :func:`jaxbelt.steering.transfer.margins`. On ``two-roller-steered``
  the once-around resonance (near ``2π / T_loop``) is what limits the gain; a plant without the
  recirculation (``k e^{−θs}/(s(1+τs))``) misses it.

**Optimiser.** Adam (optax) on the logarithms of ``(k_p, k_i)`` (positive gains, relative steps of
about ``learning_rate``), ``iterations`` steps, ``k_d`` held at the scene's value. The margins are
kept by a *feasible-direction* rule, not by penalties: a step whose end violates a margin is halved
(up to 8 times) until it meets them; the same is tried with the step's components one at a time
where the whole step does not fit, and of the feasible candidates the one with the largest
first-order decrease is taken, so every iterate is feasible and the optimiser slides along a
boundary that binds one gain. A step whose run is not finite is not taken. The start is the scene's
gains, or, where they violate a margin, those gains with ``k_p`` halved until the P-only loop meets
the margins and then ``k_i`` halved until the PI loop does (a scene without an integral gain starts
from the SIMC ratio ``k_i = k_p / (8 θ_eff)``). The result is the best iterate.

**Classical tunings**, run through the same full model for comparison:

- *SIMC* (Skogestad), PI, on the integrating-plus-delay fit the rule is made for
  (:func:`~jaxbelt.steering.plant.fit_plant`: ``k e^{−θs}/(s(1+τs))``, no
  recirculation), the lag folded into the delay by the half rule,
  ``θ_eff = θ + τ / 2``, ``τ_c = θ_eff``, ``k_p = 1 / (|k| (τ_c + θ_eff))``,
  ``k_i = k_p / (4 (τ_c + θ_eff))``;
- *Ziegler–Nichols* (ultimate point), PI: ``K_u`` and ``T_u = 2π / ω_u`` from the P-only loop on
  the measured response, ``k_p = 0.45 K_u``, ``k_i = k_p / (T_u / 1.2)``.

One loop per machine (``n_c = 1``). Gains in the reports are in mrad/mm (= rad/m),
mrad/(mm s) and mrad s/mm.
"""

from __future__ import annotations

import dataclasses
import time

import jax
import jax.numpy as jnp
import numpy as np
import optax

from ..infra.programs import stored_jit
from ..infra.results import Result
from ..model import BeltModel
from ..run_checks import belt_speed
from ..timeloop import RunOptions, simulate
from .plant import SteeringPlant, fit_plant, identify_plant
from .response import MeasuredResponse, open_loop_response
from .transfer import margins

OBJECTIVES = {"ise": "µm²·s", "peak": "µm"}
PEAK_SHARPNESS = 5.0  # β of the soft maximum, per µm
M_TO_UM = 1e6


# ------------------------------------------------------------------------------- objective

def _loop(model: BeltModel):
    loops = model.control
    if loops is None:
        raise ValueError("the model has no steering loop (no [[control]] table in its scene)")
    if loops.n_loops != 1:
        raise ValueError(f"tuning handles one steering loop; the model has {loops.n_loops}")
    return loops


def _with_gains(model: BeltModel, gains) -> BeltModel:
    g = jnp.asarray(gains, model.ell.dtype)
    kd = g[2] if g.shape[0] > 2 else None
    return model.replace(control=model.control.with_gains(g[0], g[1], kd))


@stored_jit
def _errors(model, gains, solver, dt, n_steps):
    """The sensor error ``e`` (n_steps,), m, of the closed loop with ``gains``."""
    m = _with_gains(model, gains)
    _, tr = simulate(m, solver, n_steps=n_steps, dt=dt, check=False)
    return tr.sensor_v[:, 0] - m.control.setpoint[0]


def _metric(e, dt, kind: str, skip: int):
    e = e[skip:] * M_TO_UM
    if kind == "ise":
        return jnp.sum(e * e) * dt
    if kind == "peak":
        return jax.nn.logsumexp(PEAK_SHARPNESS * jnp.abs(e)) / PEAK_SHARPNESS
    raise ValueError(f"objective = {kind!r}: one of {', '.join(OBJECTIVES)}")


def objective(model: BeltModel, gains, options: RunOptions, *, kind: str = "ise", skip_s: float = 0.5) -> jax.Array:
    """The tuning objective (module docstring) of the closed loop with ``gains`` = ``(k_p, k_i)``
    or ``(k_p, k_i, k_d)`` in SI (rad/m, rad/(m s), rad s/m) over the run ``options`` (solver,
    ``n_steps`` of ``dt``): ``ise`` in µm²·s, ``peak`` in µm. ``jnp`` throughout: ``jax.grad``
    w.r.t. ``gains`` is the exact gradient through the run."""
    _loop(model)
    if kind not in OBJECTIVES:
        raise ValueError(f"objective = {kind!r}: one of {', '.join(OBJECTIVES)}")
    dt, n_steps = options.dt, int(options.n_steps)
    e = _errors(model, jnp.asarray(gains, model.ell.dtype), options.solver, jnp.asarray(dt, model.ell.dtype), n_steps)
    return _metric(e, dt, kind, _skip_steps(skip_s, dt, n_steps))


def _skip_steps(skip_s, dt, n_steps) -> int:
    k = int(round(float(skip_s) / float(dt)))
    if not 0 <= k < int(n_steps):
        raise ValueError(f"skip_s = {skip_s}: must be at least 0 and shorter than the run ({n_steps} × {dt} s)")
    return k


def objective_and_grad(model: BeltModel, gains, options: RunOptions, *, kind: str = "ise", skip_s: float = 0.5):
    """``(value, gradient)`` of :func:`objective` w.r.t. ``(k_p, k_i)`` (SI, positive; ``k_d`` the
    model's), by reverse mode through the whole run: the compiled program :func:`tune` steps with
    (it differentiates in the logarithms of the gains; this undoes the chain rule)."""
    loops = _loop(model)
    g = np.asarray(gains, float)
    kd = jnp.asarray([float(loops.kd[0])]) if float(loops.kd[0]) > 0 else jnp.zeros((0,))
    dt, n_steps = options.dt, int(options.n_steps)
    v, gx = _log_value_and_grad(jnp.log(jnp.asarray(g)), kd, model, options.solver, jnp.asarray(dt, model.ell.dtype),
                                n_steps, kind, _skip_steps(skip_s, dt, n_steps))
    return float(v), np.asarray(gx) / g


@stored_jit
def _log_value_and_grad(log_gains, kd, model, solver, dt, n_steps, kind, skip):
    def f(x):
        e = _errors(model, jnp.concatenate([jnp.exp(x), kd]), solver, dt, n_steps)
        return _metric(e, dt, kind, skip)
    return jax.value_and_grad(f)(log_gains)


# ---------------------------------------------------------------------------- results

@dataclasses.dataclass(frozen=True)
class TuningPoint(Result):
    """One set of gains, run through the full model and checked on the plant.

    **Fields:** ``rule`` where the gains come from (``start``, ``tuned``, ``SIMC``,
    ``Ziegler–Nichols``); ``kp_mrad_per_mm``, ``ki_mrad_per_mm_s``, ``kd_mrad_s_per_mm`` the gains;
    ``objective`` the tuning objective (its unit in :attr:`TuningResult.objective_unit`);
    ``ise_um2_s`` and ``peak_um`` both measures (``peak_um`` the hard ``max |e|``) and
    ``final_error_um`` ``e`` at the end of the run; ``gain_margin_db``, ``phase_margin_deg``,
    ``crossover_rad_s`` on the identified plant; ``response_gain_margin_db``,
    ``response_phase_margin_deg`` on the measured response; ``feasible`` whether the margins meet
    the constraints (on both where the response is constrained). Margins ``None`` (in JSON) or
    ``inf`` where the loop does not cross; ``objective`` ``nan`` where the run is not finite."""

    rule: str
    kp_mrad_per_mm: float
    ki_mrad_per_mm_s: float
    kd_mrad_s_per_mm: float
    objective: float
    ise_um2_s: float
    peak_um: float
    final_error_um: float
    gain_margin_db: float
    phase_margin_deg: float
    crossover_rad_s: float
    response_gain_margin_db: float
    response_phase_margin_deg: float
    feasible: bool


@dataclasses.dataclass(frozen=True)
class TuningResult(Result):
    """:func:`tune`'s report (``jaxbelt tune --json`` is :meth:`to_dict`).

    **Fields:** ``scene`` name; ``loop`` the loop's label (``"roller/axis"``); ``objective``
    ``ise`` | ``peak``; ``objective_unit``; ``t_end_s`` the run's length and ``skip_s`` the start
    window left out; ``gm_min_db``, ``pm_min_deg`` the constraints; ``constrain_response`` whether
    the measured response is constrained too; ``plant`` the identified plant (SI,
    :class:`~jaxbelt.steering.plant.SteeringPlant`'s fields) and ``plant_source`` what identified it;
    ``response_rate`` m/s per rad, the measured walk rate; ``iterations``, ``learning_rate``;
    ``start``, ``tuned`` (:class:`TuningPoint`); ``start_note`` where the start comes from, in words
    (the scene's gains, or why others: a missing integral gain, margins the scene's gains miss);
    ``classical`` the classical tunings (:class:`TuningPoint` each); ``history`` the objective at each iterate (``nan`` where the run was
    not finite); ``improvement`` ``1 − tuned / start`` objective; ``wall_s`` seconds in all."""

    scene: str
    loop: str
    objective: str
    objective_unit: str
    t_end_s: float
    skip_s: float
    gm_min_db: float
    pm_min_deg: float
    constrain_response: bool
    plant: SteeringPlant
    plant_source: str
    response_rate: float
    iterations: int
    learning_rate: float
    start: TuningPoint
    start_note: str
    tuned: TuningPoint
    classical: tuple[TuningPoint, ...]
    history: tuple[float, ...]
    improvement: float
    wall_s: float



# ----------------------------------------------------------------------------- tuning

def simc(plant: SteeringPlant) -> tuple[float, float]:
    """SIMC PI gains ``(k_p, k_i)`` (SI) of the plant (module docstring)."""
    theta = plant.delay + plant.lag / 2
    kp = 1.0 / (abs(plant.gain) * 2 * theta)
    return kp, kp / (8 * theta)


def ziegler_nichols(ultimate_gain: float, ultimate_omega: float) -> tuple[float, float]:
    """Ziegler–Nichols PI gains ``(k_p, k_i)`` (SI) from the ultimate point: ``K_u`` rad/m (the
    P-only loop's gain margin at ``k_p = 1``) and ``ω_u`` rad/s, ``T_u = 2π/ω_u``."""
    kp = 0.45 * ultimate_gain
    return kp, kp / (2 * np.pi / ultimate_omega / 1.2)


def _db(g):
    return float(20 * np.log10(g)) if np.isfinite(g) and g > 0 else float(np.inf if g == np.inf else np.nan)


class _Check:
    """The margins of a gain vector on the plant and the response, and whether they meet the limits."""

    def __init__(self, plant, response, gm_min_db, pm_min_deg, constrain_response):
        self.plant, self.response, self.constrain = plant, response, constrain_response
        self.gm, self.pm = gm_min_db, pm_min_deg

    def margins(self, kp, ki, kd):
        gm, pm, _, w_gc = margins(self.plant, kp, ki, kd)
        rgm, rpm, _, _ = margins(self.response, kp, ki, kd)
        return _db(gm), pm, w_gc, _db(rgm), rpm

    def ok(self, kp, ki, kd):
        gm, pm, _, rgm, rpm = self.margins(kp, ki, kd)
        good = gm >= self.gm and pm >= self.pm
        return bool(good and (not self.constrain or (rgm >= self.gm and rpm >= self.pm)))


def _directions(step):
    """The Adam step and, for sliding along a boundary, the step in each coordinate alone."""
    yield step
    for i in range(step.shape[0]):
        yield jnp.zeros_like(step).at[i].set(step[i])


def _feasible_fraction(x, step, feasible, halvings: int = 8) -> float:
    """The largest ``2^-j`` (``j ≤ halvings``) with ``x + 2^-j step`` feasible, else 0."""
    frac = 1.0
    for _ in range(halvings):
        if feasible(x + frac * step):
            return frac
        frac /= 2
    return 0.0


def tune(model: BeltModel, options: RunOptions, *, kind: str = "ise", iterations: int = 40,
         learning_rate: float = 0.15, skip_s: float = 0.5, gm_min_db: float = 6.0, pm_min_deg: float = 45.0,
         constrain_response: bool = True, plant: SteeringPlant | None = None,
         response: MeasuredResponse | None = None, start=None, scene_name: str = "",
         progress: bool = False) -> TuningResult:
    """Tune the PI gains of the model's steering loop (module docstring): Adam through the whole
    closed-loop run of ``options`` (solver, ``n_steps``, ``dt``), the margins kept on the identified
    plant and the measured response, and the classical tunings beside it.

    **Arguments:** ``kind`` ``ise`` | ``peak``; ``iterations`` Adam steps; ``plant`` the identified
    plant (default: :func:`jaxbelt.steering.plant.identify_plant` on ``response``, the
    recirculating form); ``response`` the measured open-loop response (default:
    :func:`open_loop_response` over the run, at least 30 s); ``start`` ``(k_p, k_i)`` SI (default:
    the scene's gains, pulled into the feasible set); ``progress`` a progress bar.

    **Returns:** :class:`TuningResult`. ``ValueError`` for a model without exactly one loop, a
    bad ``kind`` or no feasible start."""
    from tqdm import tqdm

    t0 = time.perf_counter()
    loops = _loop(model)
    if kind not in OBJECTIVES:
        raise ValueError(f"objective = {kind!r}: one of {', '.join(OBJECTIVES)}")
    if iterations < 0:
        raise ValueError(f"iterations = {iterations}: must be at least 0")
    dt, n = float(options.dt), int(options.n_steps)
    skip = _skip_steps(skip_s, dt, n)
    if response is None:
        response = open_loop_response(model, options, t_end=max(n * dt, 30.0))
    plant_source = "given"
    if plant is None:
        loop_time = float(loops.loop_length) / belt_speed(model)
        plant, _ = identify_plant(response.t, response.step, response.rate, loop_time)
        plant_source = "jaxbelt.steering.plant.identify_plant"
    check = _Check(plant, response, gm_min_db, pm_min_deg, constrain_response)
    kd = float(loops.kd[0])

    kp0, ki0 = (float(loops.kp[0]), float(loops.ki[0])) if start is None else map(float, start)
    origin = "the scene's gains" if start is None else "the given gains"
    notes = []
    if ki0 <= 0:
        ki0 = kp0 / (8 * (plant.delay + plant.lag / 2))
        notes.append(f"no integral gain: k_i = k_p / (8 θ_eff) = {ki0:.4g} mrad/(mm s) (the SIMC ratio)")
    kp, ki = kp0, ki0
    halved = [0, 0]
    for _ in range(80):
        if check.ok(kp, ki, kd):
            break
        if check.ok(kp, 0.0, kd):
            ki /= 2
            halved[1] += 1
        else:
            kp /= 2
            halved[0] += 1
    else:
        raise ValueError(f"no feasible start from (kp, ki) = ({kp0:g}, {ki0:g}): "
                         "halving them does not meet the margins")
    if any(halved):
        notes.append(f"({kp0:.4g}, {ki0:.4g}) miss GM ≥ {gm_min_db:g} dB or PM ≥ {pm_min_deg:g}°: k_p halved "
                     f"{halved[0]} and k_i {halved[1]} time(s) until they hold")
    start_note = f"start: {origin} (k_p, k_i) = ({kp:.4g}, {ki:.4g})" + ("; " + "; ".join(notes) if notes else "")
    x = jnp.log(jnp.array([kp, ki]))
    kd_arr = jnp.asarray([kd]) if kd > 0 else jnp.zeros((0,))
    dt_arr = jnp.asarray(dt, model.ell.dtype)

    def value_and_grad(x):
        v, g = _log_value_and_grad(x, kd_arr, model, options.solver, dt_arr, n, kind, skip)
        return float(v), g

    def feasible(x):
        kp, ki = np.exp(np.asarray(x))
        return check.ok(kp, ki, kd)

    opt = optax.adam(learning_rate)
    state = opt.init(x)
    history, best = [], (np.inf, x)
    v, g = value_and_grad(x)
    bar = tqdm(range(iterations), disable=not progress, leave=False, desc=f"tune ({kind})")
    for _ in bar:
        history.append(v)
        if v < best[0]:
            best = (v, x)
        bar.set_postfix_str(f"{kind} {v:.4g} {OBJECTIVES[kind]}")
        updates, state = opt.update(g, state, x)
        moved = None
        for step in _directions(updates):  # cut back to the feasible set (feasible-direction rule)
            frac = _feasible_fraction(x, step, feasible)
            if frac > 0 and (moved is None or float(g @ (frac * step)) < float(g @ moved)):
                moved = frac * step
            if frac == 1.0:
                break
        if moved is None:
            continue  # no feasible step: stay, Adam's moments turn it
        x_new = x + moved
        v_new, g_new = value_and_grad(x_new)
        if not (np.isfinite(v_new) and bool(jnp.all(jnp.isfinite(g_new)))):
            continue
        x, v, g = x_new, v_new, g_new
    if iterations:
        history.append(v)
        if v < best[0]:
            best = (v, x)
    bar.close()

    def point(rule, kp, ki):
        e = np.asarray(_errors(model, jnp.asarray([kp, ki, kd], model.ell.dtype), options.solver, dt_arr, n))
        ee = e[skip:] * M_TO_UM
        obj = float(_metric(jnp.asarray(e), dt, kind, skip))
        finite = bool(np.all(np.isfinite(e)))
        gm, pm, w_gc, rgm, rpm = check.margins(kp, ki, kd)
        return TuningPoint(
            rule=rule, kp_mrad_per_mm=float(kp), ki_mrad_per_mm_s=float(ki), kd_mrad_s_per_mm=kd,
            objective=obj if finite else np.nan, ise_um2_s=float(np.sum(ee**2) * dt) if finite else np.nan,
            peak_um=float(np.max(np.abs(ee))) if finite else np.nan, final_error_um=float(ee[-1]),
            gain_margin_db=gm, phase_margin_deg=pm, crossover_rad_s=w_gc, response_gain_margin_db=rgm,
            response_phase_margin_deg=rpm, feasible=check.ok(kp, ki, kd))

    start_pt = point("start", kp, ki)
    kp_t, ki_t = np.exp(np.asarray(best[1]))
    tuned = point("tuned", kp_t, ki_t)
    classical = [point("SIMC", *simc(fit_plant(response)))]
    k_u, _, w_u, _ = margins(response, 1.0)  # the P-only loop at k_p = 1 on the measured response
    if np.isfinite(k_u):
        classical.append(point("Ziegler–Nichols", *ziegler_nichols(k_u, w_u)))
    return TuningResult(
        scene=scene_name, loop=loops.labels[0], objective=kind, objective_unit=OBJECTIVES[kind], t_end_s=n * dt,
        skip_s=skip * dt, gm_min_db=gm_min_db, pm_min_deg=pm_min_deg, constrain_response=constrain_response,
        plant=plant, plant_source=plant_source, response_rate=response.rate, iterations=iterations,
        learning_rate=learning_rate, start=start_pt, start_note=start_note, tuned=tuned, classical=tuple(classical),
        history=tuple(float(h) for h in history), improvement=1.0 - tuned.objective / start_pt.objective,
        wall_s=time.perf_counter() - t0)
