"""A validated reduced-model surrogate of a tolerance study (``jaxbelt sweep --rom auto``).

A :class:`Surrogate` predicts the study's metric, and the tracer deviations a sweep stores, from
a reduced model, and gives every prediction an error bound. :func:`fit_surrogate` builds it in
three stages; ``method`` chooses the reduced model.

**Training** (``1 + 2P`` full runs). The study's own model, integrator and ``n_steps`` run at
the nominal configuration (``theta = 0``) and at ``±`` the training width of each varied
component, one at a time (3σ for a normal law, the half-width for a uniform one). The response
to misalignments is nearly linear, so the nominal run plus runs along each direction span what
the sweep asks for (a model trained like that cannot extrapolate to a component no run varied,
docs/reduction.md, hence every varied component is trained). Every full run of the surrogate (training and validation)
goes through :func:`~jaxbelt.simulate` with the study's model and integrator: the program the
study compiled for its aligned reference run, so the surrogate compiles no full-order program
of its own (a vmapped batch would be cheaper per run but costs a compilation worth dozens of
serial runs).

* ``method="response"`` (default): :class:`ResponseSurface`. The training runs' tracer
  deviations themselves are the model: the nominal run ``d_0`` plus, per component, the slope
  ``(d⁺ − d⁻) / 2w`` and the curvature ``(d⁺ + d⁻ − 2d_0) / 2w²`` of its ``±w`` pair, i.e. a
  quadratic without mixed terms, exact at every training run. Only the steps the metric reads
  are kept (:func:`steps_needed`). No snapshots, no basis, no projection; a prediction is
  ``P`` multiply-adds per tracer value. It is the limit of a reduced model of the map
  ``θ → tracers`` when that map is affine, as the belt's nearly is (docs/tolerance.md), and what it leaves out — the mixed second-order terms of the 2D lever
  arms — is what the validation measures.
* ``method="pod"``: the fully reduced POD step of :mod:`jaxbelt.rom.pod_step`. The scaled
  first-order snapshots before and after each transport
  (:func:`~jaxbelt.rom.snapshots.collect_first_order`) of all training runs, side by side, give
  the POD basis (:func:`~jaxbelt.rom.pod.pod_basis`); it keeps every mode with
  ``σ_i / σ_1 > sv_tol`` (1e-9), at most ``max_modes`` (the energy rule of eq. 5.11 cannot reach
  this depth: its tail fractions, ~1e-17, are below the round-off of the cumulative sum), and
  the operators are projected at the nominal configuration
  (:func:`~jaxbelt.rom.pod_step.reduced_operators`). Online: per ``theta`` one O(N) static solve
  for the initial state, then O(r²) per step; the nominal offset (full minus reduced tracers at
  ``theta = 0``) is added, so it is exact at the nominal configuration.

**Steered machines** (``[[control]]``, ``method="response"`` only). The steering loop is part
of every full run, so the training runs' deviations are closed-loop ones, and the surface also
carries the actuators' angles in the evaluation window: the PI loop is linear in the
misalignments until its actuator clips, so angles and deviations are alike near-affine. The
validation bounds the largest angle as it bounds the metric (``steering_error_mrad``), and the
sweep re-runs in full every configuration whose predicted angle comes within that bound of the
actuator's range: the surface cannot see the clipping, the full run can. The POD step does not
carry the loop (its operators are projected with the loop open) and is refused there.

The tracers minus the study's aligned reference are the deviations in µm; the metric is formed
from them by the study's own :func:`~jaxbelt.design.metrics.response_from_deviation` and
:func:`~jaxbelt.design.metrics.aggregate`, so the full and the reduced metric share one
definition. The batch is ``vmap``-ed and compiled once: rows are padded to ``batch``.

**Bound** (``n_validation`` more full runs). ``n_validation`` fresh samples of ``dist``
(:func:`~jaxbelt.design.sampling.sample_configurations` with ``seed``) run both ways. With
``E`` the largest true metric error among them and ``ρ(θ) = ‖θ / w‖`` the distance from the
nominal in units of the training widths ``w``,

$$ \\text{bound}(θ) = \\text{safety} \\cdot E \\cdot \\max\\bigl(1, (ρ(θ)/ρ_{\\max})^2\\bigr) + ε , $$

with ``ρ_max`` the largest ``ρ`` among the validation samples, ``safety`` = 10 and ``ε`` =
1e-9 µm (round-off). Inside the validated range the bound is the constant ``safety · E``. Beyond
it the bound grows quadratically, like the error of a model linearised at the nominal (and like
the mixed terms the response surface leaves out). A configuration further out than every
validation sample therefore gets a wider bound. Such configurations lie in the far tail, which
is where a yield's failures are. ``bound_um`` is the bound on the validation samples
(``safety · E + ε``). On every validation sample it exceeds the true error at least
``safety``-fold (effectivity ≥ safety). ``validation["loo_effectivity_min"]`` gives the
leave-one-out check: each validation sample against the bound the other samples would have set.

*Why a constant and not a per-sample indicator.* A free per-sample indicator for the POD step —
the difference between the ``r``-mode model and its leading ``r/2`` modes (with a nested basis the
sub-basis operators are the leading blocks) — was calibrated the same way and did not follow the
error: with this many modes the remaining error is scattered with little dependence on the
configuration, while the constant bound held on every fresh sample and was the tighter one. The
full residual indicator (:mod:`jaxbelt.rom.error_estimate`) needs full steps for every sample, the work
the surrogate is meant to avoid. A dozen samples give a statistical statement, not a proof; the
safety factor covers that. The measured errors, bounds and speed-ups are on the benchmarks page
(the yield-with-ROM benchmark).

A prediction that is not finite gets ``bound = inf`` and ``metric = limit_um``, so the sweep
re-runs it in full.

**``--rom auto``** (``run_sweep(..., rom="auto")``, ``jaxbelt sweep --rom auto``). The sweep fits
this surrogate (``rom_method``, default ``"response"``) with ``1 + 2P`` training runs and 12
validation runs. Its bound is 10 × the largest metric error that the validation runs showed, and
it widens for configurations further out than any of them. The surrogate is used only if that
bound is below 10 % of the limit. Then every sample is predicted, and each sample whose
predicted metric lies within its own bound of the limit is re-run in full. Every pass/fail call
left to the reduced model is therefore certain up to the bound. ``full_runs`` counts the
training and validation runs (``validation.validation_runs``) plus those re-runs.
"""

from __future__ import annotations

import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..infra.programs import stored_jit
from ..rom import ReducedStep, collect_first_order, parameters, pod_basis, tracer_operator
from ..rom.pod_step import reduced_operators
from ..state import initial_state
from ..timeloop import simulate
from .metrics import METRICS
from .linearisation import LinearDeviation
from .study import Study, deviation, evaluate_deviation, linearise
from .records import SurrogateValidation
from .configurations import STEADY_CHUNK, evaluate_configs, padded_rows
from .sampling import Distribution, check_distribution, sample_configurations

ROUNDOFF_UM = 1e-9
METHODS = ("response", "pod")


class ResponseSurface(eqx.Module):
    """The tracer deviations (µm) as a function of ``theta``, from the axial training runs:
    ``d(θ) = d_0 + Σ_k (a_k θ_k + b_k θ_k²)`` with ``d_0`` the nominal run's deviations,
    ``a_k = (d_k⁺ − d_k⁻) / 2w_k`` and ``b_k = (d_k⁺ + d_k⁻ − 2 d_0) / 2w_k²`` from the runs at
    ``± w_k`` (exact at every training run; the mixed terms ``θ_j θ_k`` are what it leaves out).

    **Fields:** ``d0`` (c, m, n_tr), ``linear`` and ``curvature`` (P, c, m, n_tr): ``c`` = 1 in
    1D (longitudinal) or 2 (longitudinal, lateral); the last ``m`` steps of the run, the ones the
    study's metric reads (:func:`steps_needed`); ``n_steps`` the whole run; on a steered machine
    ``angle0`` (m, n_c), ``angle_linear`` and ``angle_curvature`` (P, m, n_c): the same surface
    for the steering actuators' angles (mrad), which the closed loop makes as linear in the
    misalignments as the tracers while no actuator saturates (``None`` without a loop)."""

    d0: jax.Array
    linear: jax.Array
    curvature: jax.Array
    n_steps: int = eqx.field(static=True)
    angle0: jax.Array | None = None
    angle_linear: jax.Array | None = None
    angle_curvature: jax.Array | None = None

    def deviations(self, theta):
        """``(d_u, d_v)`` (n_steps, n_tr) µm at ``theta`` (P,) (``d_v`` ``None`` in 1D); steps
        before the kept ones are zero (no metric reads them)."""
        theta = jnp.asarray(theta, self.d0.dtype)
        d = self.d0 + jnp.tensordot(theta, self.linear, 1) + jnp.tensordot(theta**2, self.curvature, 1)
        d = jnp.concatenate([jnp.zeros((d.shape[0], self.n_steps - d.shape[1], d.shape[2]), d.dtype), d], axis=1)
        return d[0], (d[1] if d.shape[0] > 1 else None)

    def angles(self, theta):
        """The steering actuators' angles (n_steps, n_c), mrad, at ``theta`` (``None`` without a
        loop); steps before the kept ones are zero."""
        if self.angle0 is None:
            return None
        theta = jnp.asarray(theta, self.angle0.dtype)
        a = self.angle0 + jnp.tensordot(theta, self.angle_linear, 1) + jnp.tensordot(theta**2, self.angle_curvature, 1)
        return jnp.concatenate([jnp.zeros((self.n_steps - a.shape[0], a.shape[1]), a.dtype), a], axis=0)


def steps_needed(study: Study) -> int:
    """How many of the last steps of a run the study's metric and its further limits read
    (:meth:`~jaxbelt.design.metrics.Metric.steps_read`), at least the last one the stored outputs
    read."""
    return max([1] + [METRICS[n].steps_read(study) for n in (study.metric, *study.limit_names)])


@stored_jit
def _configured(study: Study, theta):
    return study.configured(theta)


def full_deviations(study: Study, theta):
    """``(d_u, d_v, angle)`` of the full model at ``theta`` (numpy): the tracer deviations
    (n_steps, n_tr) µm (``d_v`` ``None`` in 1D) and the steering actuators' angles (n_steps,
    n_c) mrad (``None`` without a loop), one run through :func:`~jaxbelt.simulate` — the program
    the study compiled for its aligned reference run (the same shapes), so no new compilation; a
    non-finite run comes back non-finite."""
    model = _configured(study, jnp.asarray(theta, study.base.dtype))
    _, tr = simulate(model, **study.options, check=False)
    return jax.tree.map(np.asarray, deviation(study, tr.tracer_u, tr.tracer_v, tr.control_u))


@stored_jit
def _metric_jit(study: Study, du, dv, angle):
    out = evaluate_deviation(study, du, dv, angle)
    return {k: out[k] for k in ("metric", "steering_mrad") if k in out}


def _reduced_tracers(study: Study, rom: ReducedStep, theta):
    """Reduced-run tracers ``(u, v)`` (n_steps, n_tr) at ``theta``, m (``v`` ``None`` in 1D)."""
    model = study.configured(theta)
    run = rom.run(rom.project(model, initial_state(model)), parameters(model), study.options.n_steps)
    return run.tracer_u, None if study.ref_v is None else run.tracer_v


def _predict_one(study: Study, rom, anchor, theta):
    """Reduced metric and tracer deviations at t_eval. ``rom`` a :class:`ResponseSurface` or a
    :class:`~jaxbelt.rom.ReducedStep` with ``anchor`` the nominal offsets (full minus reduced
    tracers at ``theta = 0``)."""
    angle = None
    if isinstance(rom, ResponseSurface):
        du, dv = rom.deviations(theta)
        angle = rom.angles(theta)
    else:
        tu, tv = _reduced_tracers(study, rom, theta)
        du, dv, _ = deviation(study, tu + anchor[0], None if tv is None else tv + anchor[1], None)
    return evaluate_deviation(study, du, dv, angle)


@stored_jit
def _predict_batch(study: Study, rom, anchor, thetas):
    return jax.vmap(lambda th: _predict_one(study, rom, anchor, th))(thetas)


@stored_jit
def _anchor(study: Study, rom: ReducedStep, full_u, full_v):
    tu, tv = _reduced_tracers(study, rom, jnp.zeros(study.space.size))
    return full_u - tu, None if tv is None else full_v - tv


class Surrogate:
    """A fitted reduced-model surrogate (see the module docstring). Build with :func:`fit_surrogate`.

    **Attributes:** ``study``; ``rom`` the reduced model (:class:`ResponseSurface`, or
    :class:`~jaxbelt.rom.ReducedStep` with ``anchor`` its nominal offsets); ``widths`` (P,) the
    training widths ``w``; ``error_um`` (``safety · E``); ``rho_max``; ``bound_um`` (the bound
    on the validation samples, µm); ``limit_um``; ``validation`` its record
    (:class:`SurrogateValidation`, ``None`` until calibrated); on a steered
    machine ``steering_error_mrad``, the same bound for the largest actuator angle (``safety``
    times its largest validation error, growing alike beyond the validated range).
    """

    def __init__(self, study: Study, rom, anchor, widths, limit_um: float, batch: int = 64):
        self.study, self.rom, self.anchor = study, rom, anchor
        self.widths = np.asarray(widths, float)
        self.limit_um, self.batch = float(limit_um), int(batch)
        self.error_um = float("inf")
        self.steering_error_mrad = float("inf")
        self.rho_max = 0.0
        self.bound_um = float("inf")
        self.validation: SurrogateValidation | None = None

    def predict(self, thetas) -> dict:
        """Reduced ``metric`` and tracer deviations for ``thetas`` (n, P) (numpy arrays, no bound),
        ``batch`` rows at a time (one compilation)."""
        thetas = np.asarray(thetas, float).reshape(-1, self.study.space.size)
        if not len(thetas):
            return {"metric": np.zeros(0)}
        rows = padded_rows(thetas, self.batch)
        parts = [_predict_batch(self.study, self.rom, self.anchor, jnp.asarray(rows[start:start + self.batch]))
                 for start in range(0, len(rows), self.batch)]
        return {key: np.concatenate([np.asarray(p[key]) for p in parts])[:len(thetas)] for key in parts[0]}

    def distance(self, thetas) -> np.ndarray:
        """``ρ(θ) = ‖θ / w‖`` (n,): distance from the nominal in training widths."""
        return np.linalg.norm(np.asarray(thetas, float).reshape(-1, len(self.widths)) / self.widths, axis=1)

    def bound(self, thetas, error=None) -> np.ndarray:
        """Per-sample error bound (µm) on the metric (module docstring); with ``error`` the same
        growth of another validated error (the steering angle's)."""
        grow = np.maximum(1.0, (self.distance(thetas) / max(self.rho_max, 1e-300)) ** 2)
        return (self.error_um if error is None else error) * grow + ROUNDOFF_UM

    def evaluate(self, thetas) -> dict:
        """Surrogate outputs for ``thetas`` (n, P): ``metric`` (n,), ``bound`` (n,) µm, and
        ``longitudinal_um`` / ``lateral_um`` (n, n_tr) as :func:`jaxbelt.design.study.evaluate`.
        A non-finite prediction comes back with ``metric = limit_um`` and ``bound = inf``."""
        out = self.predict(thetas)
        bound = self.bound(thetas)
        bad = ~np.isfinite(bound)
        for value in out.values():
            bad |= ~np.all(np.isfinite(value.reshape(len(bad), -1)), axis=1)
        out["metric"] = np.where(bad, self.limit_um, out["metric"])
        out["bound"] = np.where(bad, np.inf, bound)
        if "steering_mrad" in out:
            out["steering_bound"] = np.where(bad, np.inf, self.bound(thetas, self.steering_error_mrad))
        return out


def training_widths(dist: Distribution, spread: float = 3.0) -> np.ndarray:
    """``w`` (P,): ``spread × σ`` for a normal law, the half-width for a uniform one."""
    return np.array([s * (spread if k == "normal" else 1.0) for k, s in zip(dist.kind, dist.scale)])


def training_configurations(dist: Distribution, spread: float = 3.0) -> np.ndarray:
    """``theta`` (1 + 2P, P) of the training runs: the nominal one, then ``±w`` of each component."""
    w = training_widths(dist, spread)
    rows = [np.zeros(len(w))]
    for j in range(len(w)):
        rows += [w[j] * np.eye(len(w))[j], -w[j] * np.eye(len(w))[j]]
    return np.array(rows)


def _fit_response(study: Study, train, widths) -> ResponseSurface:
    """:class:`ResponseSurface` from one full run per row of ``train`` (nominal, then ``±w_k``)."""
    m = steps_needed(study)
    runs, angles = [], []
    for theta in train:
        du, dv, angle = full_deviations(study, theta)
        runs.append(np.stack([np.asarray(du)] + ([] if dv is None else [np.asarray(dv)]))[:, -m:])
        if angle is not None:
            angles.append(angle[-m:])

    def surface(a, axes):  # nominal, slope and curvature of the ±w pairs
        a = np.array(a)
        w = np.asarray(widths, float).reshape((-1,) + (1,) * axes)
        return jnp.asarray(a[0]), jnp.asarray((a[1::2] - a[2::2]) / (2 * w)), \
            jnp.asarray((a[1::2] + a[2::2] - 2 * a[0]) / (2 * w**2))

    d0, linear, curvature = surface(runs, 3)
    a0, a1, a2 = surface(angles, 2) if angles else (None, None, None)
    return ResponseSurface(d0=d0, linear=linear, curvature=curvature, n_steps=study.options.n_steps,
                           angle0=a0, angle_linear=a1, angle_curvature=a2)


def _steady_surface(study: Study, linear: LinearDeviation | None) -> ResponseSurface:
    """:class:`ResponseSurface` of a steady study without a training run: the aligned steady
    state's deviations and their implicit-function derivatives (``linear``, or computed here
    where ``None``), no curvature — the linear response of steady operation, whose departure from
    the nonlinear solves the validation measures."""
    linear = linearise(study) if linear is None else linear
    (du, dv, angle), (ju, jv, jangle) = linear.at_zero, linear.derivatives
    d0 = jnp.stack([du] + ([] if dv is None else [dv]))  # (c, 1, n_tr)
    linear = jnp.moveaxis(jnp.stack([ju] + ([] if jv is None else [jv])), -1, 0)  # (P, c, 1, n_tr)
    a1 = None if angle is None else jnp.moveaxis(jangle, -1, 0)
    return ResponseSurface(d0=d0, linear=linear, curvature=jnp.zeros_like(linear), n_steps=1, angle0=angle,
                           angle_linear=a1, angle_curvature=None if a1 is None else jnp.zeros_like(a1))


def _fit_pod(study: Study, train, sv_tol: float, max_modes: int):
    """Fully reduced POD step from the training runs' snapshots, and its nominal anchor."""
    snaps = []
    for theta in train:
        _, z_pre, z_post = collect_first_order(study.configured(jnp.asarray(theta)), study.options)
        snaps += [z_pre, z_post]
    Z = jnp.concatenate(snaps, axis=1)
    x_nominal = snaps[1][:study.model.n_unknowns, 1:]  # the nominal run after each transport
    full_u = (tracer_operator(study.model) @ x_nominal).T
    full_v = None if study.ref_v is None else (tracer_operator(study.model, "z") @ x_nominal).T
    del snaps
    t_train = time.perf_counter()
    V, s = pod_basis(Z, n_modes=max_modes)
    del Z
    s = np.asarray(s)
    r = max(1, min(int(np.sum(s > sv_tol * s[0])), V.shape[1]))
    nominal = study.configured(jnp.zeros(study.space.size))
    rom = reduced_operators(nominal, V[:, :r], study.options.dt, study.options.solver, singular_values=jnp.asarray(s))
    info = {"snapshots": int(len(train) * (2 * study.options.n_steps + 1)), "n_modes": int(r), "sv_tol": float(sv_tol),
            "singular_value_ratio": float(s[r - 1] / s[0])}
    return rom, _anchor(study, rom, full_u, full_v), info, t_train


def _calibrate(surrogate: Surrogate, dist: Distribution, seed: int, n_validation: int, safety: float) -> dict:
    """Run ``n_validation`` fresh samples of ``dist`` both ways and set the surrogate's bound from
    the largest metric error (``error_um``, ``rho_max``, ``bound_um``). **Returns:** the
    validation figures of :class:`SurrogateValidation`, by field name."""
    study = surrogate.study
    thetas = sample_configurations(dist, n_validation, seed)
    if study.steady:  # one batch of steady solves (the sweep's own program for its full evaluations)
        batch = evaluate_configs(study, thetas, STEADY_CHUNK)
        runs = [{k: batch[k][i] for k in ("metric", "steering_mrad") if k in batch} for i in range(len(thetas))]
    else:
        runs = [_metric_jit(study, *full_deviations(study, th)) for th in thetas]
    full = np.array([float(r["metric"]) for r in runs])
    predicted = surrogate.predict(thetas)
    err = np.abs(predicted["metric"] - full)
    err = np.where(np.isfinite(err), err, np.inf)
    surrogate.error_um = float(safety * np.max(err))
    steering = {}
    if "steering_mrad" in predicted:
        s_err = np.abs(predicted["steering_mrad"] - np.array([float(r["steering_mrad"]) for r in runs]))
        s_err = np.where(np.isfinite(s_err), s_err, np.inf)
        surrogate.steering_error_mrad = float(safety * np.max(s_err))
        steering = {"max_true_steering_error_mrad": float(np.max(s_err)),
                    "steering_bound_mrad": surrogate.steering_error_mrad}
    surrogate.rho_max = float(np.max(surrogate.distance(thetas)))
    bound = surrogate.bound(thetas)
    surrogate.bound_um = float(np.max(bound))
    with np.errstate(divide="ignore", invalid="ignore"):
        eff = np.where(err > 0, bound / err, np.inf)
        loo = [safety * np.max(np.delete(err, i)) / err[i] if err[i] > 0 else np.inf for i in range(n_validation)]
    finite = eff[np.isfinite(eff)]
    return {
        "max_true_error_um": float(np.max(err)),
        "median_true_error_um": float(np.median(err)),
        "max_bound_um": surrogate.bound_um,
        "effectivity_min": float(finite.min()) if finite.size else float("inf"),
        "effectivity_median": float(np.median(finite)) if finite.size else float("inf"),
        "loo_effectivity_min": float(np.min(loo)),
        "metric_range_um": (float(np.min(full)), float(np.max(full))),
        **steering,
    }


def fit_surrogate(study: Study, dist: Distribution, limit_um: float, seed: int = 0, n_validation: int = 12,
                  safety: float = 10.0, sv_tol: float = 1e-9, max_modes: int = 200, spread: float = 3.0,
                  batch: int = 64, method: str = "response", linear: LinearDeviation | None = None) -> Surrogate:
    """Train, validate and calibrate a reduced-model surrogate of ``study`` under ``dist``
    (module docstring).

    **Arguments:** ``limit_um`` the sweep's limit (only to send non-finite predictions to a full
    re-run); ``seed`` of the validation samples; ``n_validation`` full runs that set the bound;
    ``safety`` factor on the largest validation error; ``spread`` the training width in σ
    (normal laws); ``batch`` rows per compiled evaluation; ``method`` the reduced model:
    ``"response"`` (:class:`ResponseSurface`, default) or ``"pod"`` (the fully reduced POD
    step, with ``sv_tol`` / ``max_modes`` its mode rule); ``linear`` a steady study's
    :class:`~jaxbelt.design.linearisation.LinearDeviation`, its surrogate (computed where not given).

    **Returns:** a :class:`Surrogate`, its ``validation`` a :class:`SurrogateValidation`.
    """
    check_distribution(dist, study)
    if method not in METHODS:
        raise ValueError(f"method = {method!r}: one of {', '.join(METHODS)}")
    if method == "pod" and study.steered:
        raise ValueError("method = 'pod': the fully reduced POD step does not carry the steering loop; "
                         "use method = 'response' on a steered machine")
    if n_validation < 2:
        raise ValueError(f"n_validation = {n_validation}: need at least 2 validation runs")
    if safety < 1.0:
        raise ValueError(f"safety = {safety}: must be at least 1")
    t0 = time.perf_counter()
    widths = training_widths(dist, spread)
    train = training_configurations(dist, spread)
    if study.steady and method != "response":
        raise ValueError(f"method = {method!r}: steady operation's surrogate is its linear response (method = 'response')")
    if study.steady:  # the implicit tangents of the aligned steady state: no training solve
        train = train[:0]
        rom, anchor, info = _steady_surface(study, linear), None, {"steps_kept": 1}
        t_train = t_fitted = time.perf_counter()
    elif method == "response":
        rom, anchor, info = _fit_response(study, train, widths), None, {"steps_kept": steps_needed(study)}
        t_train = t_fitted = time.perf_counter()
    else:
        rom, anchor, info, t_train = _fit_pod(study, train, sv_tol, max_modes)
        t_fitted = time.perf_counter()
    surrogate = Surrogate(study, rom, anchor, widths, limit_um, batch)
    t2 = time.perf_counter()
    checks = _calibrate(surrogate, dist, seed, n_validation, safety)
    t_full = time.perf_counter() - t2
    described = "linear response of steady operation (implicit derivatives of the aligned steady state)" \
        if study.steady else {
            "response": "response surface of the tracer deviations (nominal run + per-component slope and curvature "
                        "from the +-w runs)",
            "pod": "fully reduced POD step (jaxbelt.rom), nominal-anchored",
        }[method]
    surrogate.validation = SurrogateValidation(
        method=method,
        description=described + "; bound = safety x largest validation error, growing with (rho / rho_max)^2 "
                                "beyond the validated range",
        validation_runs=int(len(train) + n_validation),
        training_runs=int(len(train)),
        n_validation=int(n_validation),
        seed=int(seed),
        training_widths=tuple(widths.tolist()),
        **info,
        safety=float(safety),
        rho_max=surrogate.rho_max,
        **checks,
        training_s=t_train - t0,
        fit_s=t_fitted - t_train,
        validation_s=t_full,
        offline_s=time.perf_counter() - t0,
        unit=study.unit,
    )
    return surrogate
