"""Yield under random misalignments: Monte Carlo, FORM and importance sampling.

A *distribution* gives every varied component an independent law around the scene's own
misalignment, in design units (mm / mrad): ``normal`` with standard deviation ``σ`` or
``uniform`` on ``[-h, h]``. Both are written as transforms of a standard normal variable
``u`` (the FORM space): ``θ = σ u`` and ``θ = h (2Φ(u) - 1)``. The limit state is

$$ g(u) = \\text{limit} - \\text{metric}(θ(u)), \\qquad \\text{pass} \\iff g \\ge 0, $$

and the *yield* is ``P(g ≥ 0)``.

- **Monte Carlo** (:func:`monte_carlo`): ``n`` samples, evaluated in batches
  (:func:`jaxbelt.design.configurations.evaluate_configs`); the yield with a Wilson score 95 %
  interval (:func:`yield_estimate`, the one estimate of every Monte-Carlo yield, a sweep's too).
- **FORM** (:func:`form`): the design point ``u*`` (the most probable failing configuration)
  by Hasofer–Lind–Rackwitz–Fiessler iterations with the gradient of the metric through the
  whole run, started from the linearised response; ``β = ‖u*‖``, yield ``Φ(β)``. For a
  max-type metric the failure set is a union over tracers and signs, and FORM sees its most
  probable member only (an upper bound on the yield when several compete).
- **Importance sampling** (:func:`importance_sampling`) around ``u*`` for yields near 1:
  ``u ~ N(u*, I)``, weights ``φ(u)/φ(u - u*)``.

:func:`yield_statistics` is everything a yield study (:func:`jaxbelt.design.run_sweep`) reads
from its evaluated samples in one call: the Monte-Carlo estimate, and with the linear response FORM
and — where the samples saw few failures, :func:`few_failures` — importance sampling.
"""

from __future__ import annotations

import dataclasses
import math

import jax
import jax.numpy as jnp
import numpy as np
from jax.scipy.stats import norm

from ..misalignment import COMPONENTS, TRANSLATIONS, parameter_space
from ..infra.programs import stored_jit
from .linearisation import LinearDeviation
from .configurations import evaluate_configs, evaluate_metric
from .study import Study, metric_value
from .sensitivity import response_jacobian
from ..infra.results import Result

DISTRIBUTIONS = ("normal", "uniform")
Z95 = 1.959963984540054  # the standard normal's 97.5 % quantile: every 95 % interval here


@dataclasses.dataclass(frozen=True)
class Distribution:
    """Independent laws per varied component: ``labels`` ("roller:component", P), ``kind``
    (P,) "normal" | "uniform", ``scale`` (P,) σ or half-width (mm / mrad)."""

    labels: tuple
    kind: tuple
    scale: tuple

    @property
    def components(self) -> list[str]:
        return list(self.labels)

    @property
    def uniform(self) -> tuple:
        """(P,) whether each law is uniform (else normal)."""
        return tuple(k == "uniform" for k in self.kind)

    @property
    def sigma(self) -> tuple:
        """(P,) each law's standard deviation (mm / mrad): ``σ``, or ``h / √3`` for a uniform law."""
        return tuple(s / math.sqrt(3.0) if u else s for s, u in zip(self.scale, self.uniform))

    def transform(self, u):
        """Standard normal ``u`` (..., P) → misalignments ``θ`` (..., P)."""
        return misalignments_of(jnp.asarray(self.scale), jnp.asarray(self.uniform), u)

    def to_dict(self) -> dict:
        return {lab: {"dist": k, "scale": s} for lab, k, s in zip(self.labels, self.kind, self.scale)}


def misalignments_of(scale, uniform, u):
    """The misalignments ``θ`` (..., P) of standard normal ``u`` under laws of ``scale`` (P,) (σ or
    half-width), ``uniform`` (P,) a mask of the uniform ones (module docstring): ``jnp``, the one
    transform of the sampling and of FORM's limit state."""
    return jnp.where(uniform, scale * (2.0 * norm.cdf(u) - 1.0), scale * u)


def sample_configurations(dist: Distribution, n: int, seed: int) -> np.ndarray:
    """The configurations (n, P) of ``seed`` under ``dist``: the first ``n`` of the seed's sequence
    (:func:`standard_normal_samples`), the same for every ``n`` (a resumed sweep relies on that)."""
    # jit: one small program instead of compiling norm.cdf's primitives one by one (~2 s)
    return np.asarray(jax.jit(dist.transform)(jnp.asarray(standard_normal_samples(n, len(dist.labels), seed))))


def distribution_from_dict(data: dict, model) -> Distribution:
    """Validate a distribution table (the ``--dist`` TOML file) against a model.

    Format: ``[roller."NAME"]`` tables with ``translation_mm`` and/or ``rotation_mrad``, each
    ``{dist = "normal", sigma = [x, y, z]}`` or ``{dist = "uniform", half_width = [x, y, z]}``.
    Zero entries are not varied. Raises ``ValueError`` naming the key and value.
    """
    if not isinstance(data, dict) or set(data) - {"roller"}:
        raise ValueError(f"distribution file: unknown table(s) {sorted(set(data) - {'roller'})} (only [roller.\"NAME\"])")
    rollers = data.get("roller", {})
    if not isinstance(rollers, dict) or not rollers:
        raise ValueError("distribution file: no [roller.\"NAME\"] table")
    labels, kinds, scales = [], [], []
    space = parameter_space(model)
    for name, table in rollers.items():
        if name not in model.roller_names:
            raise ValueError(f"roller.{name!r}: no roller of that name (rollers: {', '.join(model.roller_names)})")
        if not isinstance(table, dict):
            raise ValueError(f"roller.{name!r}: must be a table")
        for group, spec in table.items():
            where = f"roller.{name!r}.{group}"
            if group not in ("translation_mm", "rotation_mrad"):
                raise ValueError(f"{where}: unknown key (translation_mm or rotation_mrad)")
            if not isinstance(spec, dict) or "dist" not in spec:
                raise ValueError(f"{where}: must be {{dist = \"normal\", sigma = [...]}} or {{dist = \"uniform\", half_width = [...]}}")
            dist = spec["dist"]
            if dist not in DISTRIBUTIONS:
                raise ValueError(f"{where}.dist = {dist!r}: unknown distribution (one of {', '.join(DISTRIBUTIONS)})")
            key = "sigma" if dist == "normal" else "half_width"
            extra = set(spec) - {"dist", key}
            if extra:
                raise ValueError(f"{where}: unknown key(s) {sorted(extra)} for dist = {dist!r} (expects {key})")
            vals = spec.get(key)
            if not isinstance(vals, list) or len(vals) != 3 or not all(isinstance(v, (int, float)) for v in vals):
                raise ValueError(f"{where}.{key} = {vals!r}: must be a list of 3 numbers")
            for k, v in enumerate(vals):
                if not math.isfinite(v):
                    raise ValueError(f"{where}.{key}[{k}] = {v}: must be finite")
                if v < 0:
                    raise ValueError(f"{where}.{key}[{k}] = {v}: must not be negative")
                if v == 0:
                    continue
                comp = (TRANSLATIONS if group == "translation_mm" else ("ax", "ay", "az"))[k]
                label = f"{name}:{comp}"
                if label not in space.labels():
                    j = model.roller_names.index(name)
                    why = dict(space.structural).get((j, comp), "not a parameter")
                    raise ValueError(f"{where}.{key}[{k}] = {v}: {label} cannot vary ({why})")
                labels.append(label)
                kinds.append(dist)
                scales.append(float(v))
    if not labels:
        raise ValueError("distribution file: every σ / half-width is zero; nothing varies")
    order = sorted(range(len(labels)), key=lambda i: (model.roller_names.index(labels[i].split(":")[0]),
                                                      COMPONENTS.index(labels[i].split(":")[1])))
    return Distribution(tuple(labels[i] for i in order), tuple(kinds[i] for i in order),
                        tuple(scales[i] for i in order))


def check_distribution(dist: Distribution, study: Study):
    if list(dist.labels) != study.space.labels():
        raise ValueError(f"the study varies {study.space.labels()}, the distribution {list(dist.labels)}")


def passes(metric, limit_um: float, saturated=None) -> np.ndarray:
    """The one pass rule of every yield (Monte Carlo here, :func:`jaxbelt.design.run_sweep`):
    the metric within the limit **and**, on a steered machine, the actuator not saturated — a loop
    at its range no longer holds the belt, whatever the metric reads (``saturated`` ``None``
    without a loop). A NaN metric (an unconverged solve) fails."""
    ok = np.asarray(metric) <= limit_um
    return ok if saturated is None else ok & ~np.asarray(saturated, bool)


# ----------------------------------------------------------------------------- statistics


def yield_estimate(metric, limit_um: float, saturated=None) -> tuple[int, tuple[float, float]]:
    """A Monte-Carlo yield from every sample's ``metric`` (n,) (and, on a steered machine, whether
    its actuator ``saturated``): ``(passed, ci95)``, the samples that pass (:func:`passes`) and the
    Wilson 95 % interval of their fraction (:func:`wilson_interval`); the yield is ``passed / n``."""
    passed = int(np.sum(passes(metric, limit_um, saturated)))
    return passed, wilson_interval(passed, len(np.asarray(metric)))


def wilson_interval(passed: int, n: int, z: float = Z95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion (95 % by default)."""
    if n <= 0:
        raise ValueError(f"n = {n}: need at least one sample")
    p = passed / n
    den = 1 + z**2 / n
    centre = (p + z**2 / (2 * n)) / den
    half = z * math.sqrt(p * (1 - p) / n + z**2 / (4 * n**2)) / den
    return max(0.0, centre - half), min(1.0, centre + half)


def standard_normal_samples(n: int, P: int, seed: int) -> np.ndarray:
    """The ``u`` samples (n, P) of a seed: the same seed always gives the same configurations,
    in the same order (a resumed sweep relies on that)."""
    return np.random.default_rng(seed).standard_normal((n, P))


@dataclasses.dataclass(frozen=True)
class SampleOutputs(Result):
    """What :func:`~jaxbelt.design.study.evaluate` gives for every sample, leading axis n:
    **Fields:** ``metric`` (n,) in the metric's unit; ``longitudinal_um`` and (2D, else
    ``None``) ``lateral_um`` (n, n_tr) the tracer deviations at ``t_eval``, µm; on a steered
    machine (else ``None``) ``steering_mrad`` (n,) the largest actuator angle in the window, mrad,
    and ``saturated`` (n,) whether the actuator reached its range limit there."""

    metric: np.ndarray
    longitudinal_um: np.ndarray
    lateral_um: np.ndarray | None = None
    steering_mrad: np.ndarray | None = None
    saturated: np.ndarray | None = None


@dataclasses.dataclass(frozen=True)
class MonteCarloResult(Result):
    """A Monte-Carlo yield (:func:`monte_carlo`). **Fields:** ``yield_`` the fraction of samples
    that pass (:func:`passes`: on a steered machine a saturated actuator fails); ``ci95`` its
    Wilson 95 % interval; ``samples``; ``passed``; ``theta`` (n, P) the configurations, mm / mrad;
    ``metric`` (n,) their metric; ``outputs`` everything :func:`~jaxbelt.design.study.evaluate`
    returned, per sample (:class:`SampleOutputs`)."""

    yield_: float
    ci95: tuple
    samples: int
    passed: int
    theta: np.ndarray
    metric: np.ndarray
    outputs: SampleOutputs


def monte_carlo(study: Study, dist: Distribution, n: int, limit_um: float, seed: int = 0,
                chunk: int | None = None, progress=None) -> MonteCarloResult:
    """Monte-Carlo yield with a Wilson 95 % interval (:class:`MonteCarloResult`)."""
    check_distribution(dist, study)
    if n <= 0:
        raise ValueError(f"samples = {n}: must be at least 1")
    thetas = sample_configurations(dist, n, seed)
    out = evaluate_configs(study, thetas, chunk, progress)
    metric = np.asarray(out["metric"])
    passed, ci95 = yield_estimate(metric, limit_um, out.get("saturated"))
    return MonteCarloResult(yield_=passed / n, ci95=ci95, samples=n, passed=passed,
                            theta=thetas, metric=metric,
                            outputs=SampleOutputs(**{k: np.asarray(v) for k, v in out.items()}))


@stored_jit
def _g_and_grad(study, dist_scale, uniform, u, limit):
    def g(u):
        return limit - metric_value(study, misalignments_of(dist_scale, uniform, u), smooth=True)

    return jax.value_and_grad(g)(u)


@dataclasses.dataclass(frozen=True)
class FormResult(Result):
    """First-order reliability (:func:`form`). **Fields:** ``beta`` the reliability index
    (negative when the nominal configuration fails); ``yield_`` ``Φ(β)``; ``u_star`` (P,) the
    design point in the standard normal space; ``theta_star`` (P,) the same in mm / mrad;
    ``iterations``; ``converged``; ``g_star_um`` the limit-state function there (≈ 0);
    ``series_bounds`` (max-type metrics, else ``None``) the first-order bounds of a series
    system ``[1 - Σ_j Φ(-β_j), 1 - max_j Φ(-β_j)]`` over the linearised failure modes."""

    beta: float
    yield_: float
    u_star: np.ndarray
    theta_star: np.ndarray
    iterations: int
    converged: bool
    g_star_um: float
    series_bounds: tuple | None = None


def form(study: Study, dist: Distribution, limit_um: float, u0=None, max_iter: int = 30,
         tol: float = 1e-6, linear: LinearDeviation | None = None, response=None) -> FormResult:
    """First-order reliability: the design point by HL-RF iterations (module docstring).

    The start point ``u0`` defaults to the design point of the linearised response's most
    critical row (see :func:`linear_design_point`); the linear response is read from ``linear``
    (the study's :class:`~jaxbelt.design.linearisation.LinearDeviation`) where given, else from a run;
    ``response`` ``(r0, J)`` (:func:`~jaxbelt.design.sensitivity.response_jacobian`) where the caller
    already holds it.

    **Returns:** a :class:`FormResult`; its ``series_bounds`` (max-type metrics) bound the yield
    over all linearised failure modes, of which FORM's single design point sees only the most
    probable one."""
    check_distribution(dist, study)
    scale, uniform = jnp.asarray(dist.scale), jnp.asarray(dist.uniform)
    r0, J = response_jacobian(study, linear=linear) if response is None else response
    if u0 is None:
        u0 = linear_design_point(r0, J, dist, limit_um, study.aggregate)
    u = jnp.asarray(u0, float)
    converged, it = False, 0
    for it in range(1, max_iter + 1):
        g, dg = _g_and_grad(study, scale, uniform, u, limit_um)
        nd = float(jnp.dot(dg, dg))
        if nd == 0.0:
            break
        u_new = (jnp.dot(dg, u) - g) / nd * dg
        step = float(jnp.linalg.norm(u_new - u))
        u = u_new
        if step < tol * max(1.0, float(jnp.linalg.norm(u))) and abs(float(g)) < 1e-6 * limit_um:
            converged = True
            break
    g, _ = _g_and_grad(study, scale, uniform, u, limit_um)
    g0, _ = _g_and_grad(study, scale, uniform, jnp.zeros_like(u), limit_um)
    beta = float(jnp.linalg.norm(u)) * (1.0 if float(g0) >= 0 else -1.0)  # negative: the nominal fails
    bounds = None
    if study.aggregate == "max":
        pf = norm.cdf(-_mode_betas(r0, J, dist, limit_um)[0])
        bounds = (max(0.0, 1.0 - float(jnp.sum(pf))), 1.0 - float(jnp.max(pf)))
    return FormResult(beta=beta, yield_=float(norm.cdf(beta)), u_star=np.asarray(u),
                      theta_star=np.asarray(dist.transform(u)), iterations=it, converged=converged,
                      g_star_um=float(g), series_bounds=bounds)


def _mode_betas(r0, J, dist: Distribution, limit_um: float):
    """Reliability indices of every failure mode ``s r_i > limit`` (row ``i``, sign ``s``) of
    the response linearised at ``u = 0``: ``β = (limit - s r0_i) / ‖J_i D‖`` with ``D = σ``
    (normal) or ``2 φ(0) h`` (uniform). **Returns:** ``(β (n_r, 2), J D)``."""
    D = np.array([s * (2 * 0.3989422804014327 if u else 1.0) for u, s in zip(dist.uniform, dist.scale)])
    JD = np.asarray(J) * D
    norms = np.linalg.norm(JD, axis=1)
    beta = np.full((len(r0), 2), np.inf)
    ok = norms > 0
    for c, s in enumerate((1.0, -1.0)):
        beta[ok, c] = (limit_um - s * np.asarray(r0)[ok]) / norms[ok]
    return beta, JD


def linear_design_point(r0, J, dist: Distribution, limit_um: float, kind: str) -> np.ndarray:
    """Design point of the response linearised at ``u = 0``: for a max-type metric that of the
    failure mode with the smallest ``β`` (:func:`_mode_betas`), for an RMS metric the leading
    singular direction of ``J D`` scaled onto the limit."""
    beta, JD = _mode_betas(r0, J, dist, limit_um)
    if kind == "max":
        i, c = np.unravel_index(np.argmin(beta), beta.shape)
        return beta[i, c] * (1.0 if c == 0 else -1.0) * JD[i] / np.linalg.norm(JD[i])
    _, sv, vt = np.linalg.svd(JD, full_matrices=False)
    return limit_um * np.sqrt(JD.shape[0]) / max(sv[0], 1e-300) * vt[0]


@dataclasses.dataclass(frozen=True)
class ImportanceSamplingResult(Result):
    """A yield by importance sampling (:func:`importance_sampling`). **Fields:** ``yield_``;
    ``ci95`` its normal-approximation 95 % interval; ``failure_probability``; ``std_error`` of
    that estimate; ``samples``."""

    yield_: float
    ci95: tuple
    failure_probability: float
    std_error: float
    samples: int


def importance_sampling(study: Study, dist: Distribution, limit_um: float, u_star, n: int = 1000,
                        seed: int = 1, chunk: int | None = None, metric_of=None) -> ImportanceSamplingResult:
    """Yield by importance sampling around the design point ``u_star``
    (:class:`ImportanceSamplingResult`); ``metric_of(thetas (n, P)) -> (n,)`` evaluates the samples
    (default: the full model, :func:`evaluate_metric`)."""
    check_distribution(dist, study)
    u_star = np.asarray(u_star, float)
    u = u_star + np.random.default_rng(seed).standard_normal((n, len(u_star)))
    w = np.exp(-u @ u_star + 0.5 * u_star @ u_star)
    thetas = np.asarray(dist.transform(jnp.asarray(u)))
    metric = evaluate_metric(study, thetas, chunk) if metric_of is None else np.asarray(metric_of(thetas))
    fail = (~passes(metric, limit_um)).astype(float)  # the metric only (module docstring); NaN fails
    pf = float(np.mean(fail * w))
    se = float(np.std(fail * w, ddof=1) / math.sqrt(n)) if n > 1 else float("inf")
    return ImportanceSamplingResult(yield_=1.0 - pf, ci95=(max(0.0, 1.0 - pf - Z95 * se), min(1.0, 1.0 - pf + Z95 * se)),
                                    failure_probability=pf, std_error=se, samples=n)


def few_failures(failed: int, n: int) -> bool:
    """Whether ``n`` Monte-Carlo samples with ``failed`` failures leave the yield's tail to
    importance sampling: at most 5 failures, or 0.1 % of the samples — a yield so near 1 that the
    samples' own count says little about it."""
    return failed <= max(5, int(0.001 * n))


@dataclasses.dataclass(frozen=True)
class YieldStatistics(Result):
    """A yield from evaluated samples (:func:`yield_statistics`). **Fields:** ``passed`` and
    ``samples``, the Monte-Carlo count (:func:`yield_estimate`), ``ci95`` the Wilson 95 % interval of
    ``passed / samples``; ``form`` (:class:`FormResult`) with a linear response, else ``None``;
    ``importance`` (:class:`ImportanceSamplingResult`) where FORM ran and the samples saw few
    failures (:func:`few_failures`) with the nominal configuration passing, else ``None``."""

    passed: int
    samples: int
    ci95: tuple
    form: FormResult | None = None
    importance: ImportanceSamplingResult | None = None


def yield_statistics(study: Study, dist: Distribution, limit_um: float, metric, saturated=None, *,
                     response=None, importance_samples: int = 200, seed: int = 1, chunk: int | None = None,
                     metric_of=None) -> YieldStatistics:
    """The statistics of a yield from every sample's ``metric`` (n,) (and, on a steered machine,
    whether its actuator ``saturated``): the Monte-Carlo estimate (:func:`yield_estimate`); with
    ``response`` ``(r0, J)`` (:func:`~jaxbelt.design.sensitivity.response_jacobian`) also FORM
    (:func:`form`) and, where the samples saw few failures (:func:`few_failures`) and the nominal
    configuration passes (``β > 0``), importance sampling around FORM's design point
    (:func:`importance_sampling`: ``importance_samples`` of ``seed``, ``chunk`` per batch,
    evaluated by ``metric_of`` or the full model). **Returns:** a :class:`YieldStatistics`."""
    metric = np.asarray(metric)
    passed, ci95 = yield_estimate(metric, limit_um, saturated)
    if response is None:
        return YieldStatistics(passed, len(metric), ci95)
    f = form(study, dist, limit_um, response=response)
    importance = None
    if few_failures(len(metric) - passed, len(metric)) and f.beta > 0:
        importance = importance_sampling(study, dist, limit_um, f.u_star, n=importance_samples, seed=seed,
                                         chunk=chunk, metric_of=metric_of)
    return YieldStatistics(passed, len(metric), ci95, f, importance)
