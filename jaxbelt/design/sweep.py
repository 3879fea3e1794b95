"""The yield study behind ``jaxbelt sweep``: Monte Carlo in chunks, stored and resumable, with
FORM / importance sampling beside it and a reduced model standing in where it is trusted.

Per chunk of configurations (fixed by the seed, :func:`~jaxbelt.design.sampling.sample_configurations`):

1. full model only (``rom="off"``): every configuration runs in full, batched and sharded;
2. ``rom="auto"``: a surrogate (:mod:`jaxbelt.design.surrogate`) is fitted and *validated* on
   separate samples against full runs; it stands in only if its error bound there is below
   10 % of the limit. Then every configuration is predicted by it, and those whose predicted
   metric lies within the bound of the limit are re-run in full (so the pass/fail call of a
   reduced sample is certain up to the bound). Otherwise the sweep falls back to full runs.
   In steady operation (a steady study) the surrogate is the steady state's linear response:
   the implicit derivatives the study already holds, no training solve; its validation solves
   and the re-runs near the limit are steady solves, and the importance samples are evaluated
   the same way.

Each finished chunk is appended to the Zarr store (``out``), so a rerun resumes.

**Several limits** (a study from :func:`~jaxbelt.design.study.with_limits`; ``jaxbelt sweep`` on a
steered machine, as ``jaxbelt tolerance``: lateral and longitudinal deviation and the actuator
angle): the metric is the largest value over its limit, on the scale of the first limit, so a
configuration passes where every limit holds, and everything below (the surrogate's bound, FORM,
importance sampling) reads that one number.

On a steered machine (``[[control]]``) a configuration *fails* when its metric exceeds the limit
**or** its steering actuator saturates in the evaluation window (an angle within 0.1 % of its
range: :func:`jaxbelt.design.metrics.saturation`): a loop at its range no longer holds the belt,
and past it the response is no longer the linear one. ``saturated`` counts them. FORM and
importance sampling see the metric only. With ``rom="auto"`` the response-surface surrogate
carries the loop (its training runs are closed-loop runs, and it predicts the actuator angles
too); a configuration whose predicted angle comes within the surrogate's steering bound of the
range is re-run in full, so a saturation is never left to the reduced model. The POD surrogate
does not carry the loop: with ``rom_method="pod"`` the sweep says so in ``rom.reason`` and
runs every configuration in full.
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from ..accuracy import Grid
from ..infra.results import Result, in_metric_unit, json_fields, not_in_json, to_json, unit_key
from ..infra.store import MODEL_CODES, append_chunk, load_sweep, open_sweep
from ..timeloop import RunOptions
from .linear_box import LinearResponse, rss_stackup
from .linearisation import LinearDeviation
from .metrics import SATURATION_FRACTION, metric_unit, on_limit_scale
from .configurations import evaluate_configs
from .sampling import Distribution, YieldStatistics, check_distribution, sample_configurations, yield_statistics
from .sensitivity import response_jacobian
from .records import MetricLimit, RollerMisalignment, SurrogateValidation, misalignment_per_roller
from .study import Study, study_on
from .surrogate import Surrogate, fit_surrogate

FLIP_BAND = 0.10  # yield error bar: samples within this fraction of the limit are re-run one grid finer
MIN_RECHECKED = 2  # ... and at least this many, the nearest (the metric's relative change)
ROM_TRUST_FRACTION = 0.10  # the surrogate's validated error bound must stay below this × limit
ROM_STEERED = ("the POD surrogate does not carry the steering loop (use the response surface, --rom-method response); "
               "every configuration runs in full")


@dataclasses.dataclass(frozen=True)
class ReducedModelUse(Result):
    """Whether a reduced model stood in for the full runs of a sweep (:func:`run_sweep`).
    **Fields:** ``used``; ``reason`` why ``rom="auto"`` was refused (a steered machine's POD
    surrogate), else ``None``; ``validation`` the fitted surrogate's record
    (:class:`~jaxbelt.design.records.SurrogateValidation`, used or not), ``None`` without one.

    :meth:`to_dict` is one flat record: the validation's entries, ``used``, and ``reason`` where
    there is one."""

    used: bool
    reason: str | None = None
    validation: SurrogateValidation | None = None

    @property
    def validation_runs(self) -> int:
        """The surrogate's training and validation full runs (0 without one)."""
        return 0 if self.validation is None else self.validation.validation_runs

    def to_dict(self) -> dict:
        """``{**validation, "used": ..., "reason": ...}``, the parts that are ``None`` left out."""
        out = {} if self.validation is None else self.validation.to_dict()
        out["used"] = bool(self.used)
        if self.reason is not None:
            out["reason"] = self.reason
        return to_json(out)


@dataclasses.dataclass(frozen=True)
class SweepResult(Result):
    """The yield study of :func:`run_sweep`.

    **Fields:**

    - ``metric``, ``limit_um``, ``samples``, ``seed``: the question; ``limits`` with several limits
      (:func:`~jaxbelt.design.study.with_limits`) each one (:class:`~jaxbelt.design.records.MetricLimit`): the
      metric is then the largest value over its limit times ``limit_um`` (the first limit), and a
      configuration passes where every limit holds; ``None`` with one limit.
    - ``yield_``: the fraction of the ``samples`` configurations whose metric is ≤ the limit
      (and, on a steered machine, whose actuator does not saturate); ``ci95`` its Wilson 95 %
      interval; ``passed`` their number.
    - ``saturated``: on a steered machine, the configurations whose steering actuator reached its
      range limit in the evaluation window, each counted as a failure whatever its metric;
      ``range_mrad`` that range; ``steering_max_mrad`` the largest actuator angle of any
      configuration; all ``None`` without a loop.
    - ``full_runs``: configurations run with the full model, the surrogate's training and
      validation runs included (used or not); ``reduced_runs``: configurations the surrogate
      decided.
    - ``rom``: whether a surrogate stood in and its validation record (:class:`ReducedModelUse`).
    - ``unit``: the unit of ``limit_um``, ``metric_values`` and ``rss_3sigma_um`` (the metric's: µm,
      mrad or µm/s; the first limit's with several limits); the JSON keys of the first and last name
      it (:func:`jaxbelt.infra.results.unit_key`).
    - ``metric_values`` (samples,): the metric of every configuration; ``configurations`` (samples,
      P) the configurations themselves (the seed's draw, mm / mrad, the columns those of the study's
      components), which the JSON leaves out (it names the seed and the distribution, which draw them).
    - ``speedup_estimate``: with a reduced model, the full model's time per configuration in the
      validation runs (compilation included) times the configurations run, over the wall time —
      indicative (``benchmarks/yield_rom.py`` measures it side by side); else ``None``.
    - ``rss_3sigma_um``: the linear statistical stack-up (``σ`` of a uniform law ``h/√3``);
      ``form_yield``, ``form_beta``, ``form_converged``, ``design_point`` (per roller,
      :class:`~jaxbelt.design.records.RollerMisalignment`, mm / mrad): FORM (:func:`~jaxbelt.design.sampling.form`); all ``None`` without FORM.
    - ``is_yield``, ``is_ci95``, ``is_samples``: importance sampling around the design point, run
      when no or few samples failed (yield near 1), else ``None``.
    - ``wall_s``: the sweep's wall time; ``configs_per_s``: configurations evaluated in this call
      per second of it.
    """

    metric: str
    limit_um: float = in_metric_unit()
    samples: int
    seed: int
    yield_: float
    ci95: list
    passed: int
    full_runs: int
    reduced_runs: int
    rom: ReducedModelUse
    metric_values: np.ndarray
    wall_s: float
    configs_per_s: float
    speedup_estimate: float | None = None
    saturated: int | None = None
    range_mrad: float | None = None
    steering_max_mrad: float | None = None
    rss_3sigma_um: float | None = in_metric_unit(default=None)
    form_yield: float | None = None
    form_beta: float | None = None
    form_converged: bool | None = None
    design_point: dict[str, RollerMisalignment] | None = None
    is_yield: float | None = None
    is_ci95: list | None = None
    is_samples: int | None = None
    limits: tuple[MetricLimit, ...] | None = None
    unit: str = "µm"
    configurations: np.ndarray | None = not_in_json()

    def to_dict(self, values: bool = False) -> dict:
        """The result as JSON-able data (``jaxbelt sweep --json``): ``yield_`` as ``"yield"``, the
        fields that are ``None`` left out, ``metric_values`` only with ``values``, metric values
        keyed by ``unit``; the ``configurations`` are not written."""
        fields = json_fields(self)
        for k in ("wall_s", "configs_per_s"):  # the timings close the record
            fields[k] = fields.pop(k)
        return to_json({("yield" if k == "yield_" else k): v.to_dict() if k == "rom" else v
                        for k, v in fields.items() if v is not None and (values or k != "metric_values")})


def sweep_identity(study: Study, dist: Distribution, n: int, limit_um: float, seed: int, scene: str = "") -> dict:
    """What a stored sweep is of (its store resumes only a sweep with the same identity)."""
    return _identity(study, study.t_eval, study.limits, dist.to_dict(), limit_um, seed, scene)


def _identity(study, t_eval, limits, distribution: dict, limit_um, seed, scene) -> dict:
    return {"scene": scene, "metric": study.metric, "t_eval_s": t_eval, unit_key("limit_um", study.unit): float(limit_um),
            "limits": [[n, float(v)] for n, v in limits],
            "seed": int(seed), "distribution": distribution,
            "tracers": int(study.ref_u.shape[1])}


def _check(n, limit_um, rom, rom_method):
    if not (np.isfinite(limit_um) and limit_um > 0):
        raise ValueError(f"limit_um = {limit_um}: must be a positive number")
    if n < 1:
        raise ValueError(f"samples = {n}: must be at least 1")
    if rom not in ("off", "auto"):
        raise ValueError(f"rom = {rom!r}: one of off, auto")
    if rom_method not in ("response", "pod"):
        raise ValueError(f"rom_method = {rom_method!r}: one of response, pod")


def _surrogate(study, dist, limit_um, seed, rom_method, linear) -> tuple[Surrogate | None, ReducedModelUse]:
    """The validated surrogate, or ``None`` where its bound is not below the trust fraction of
    the limit; and its record."""
    surrogate = fit_surrogate(study, dist, limit_um, seed=seed + 7919, method=rom_method, linear=linear)
    use = ReducedModelUse(used=bool(surrogate.bound_um < ROM_TRUST_FRACTION * limit_um),
                          validation=surrogate.validation)
    return (surrogate if use.used else None), use


def _chunk_outputs(study, surrogate, block, limit_um, chunk):
    """One chunk's outputs and model codes: full runs, or the surrogate with full re-runs of the
    configurations whose prediction lies within its bound of the limit."""
    if surrogate is None:
        return evaluate_configs(study, block, chunk), np.full(len(block), MODEL_CODES["full"], np.int8)
    res = {k: np.array(v) for k, v in surrogate.evaluate(block).items()}
    near = np.abs(res["metric"] - limit_um) <= res.pop("bound")
    if "steering_mrad" in res:  # the surface cannot see the actuator clip: near the range, run in full
        near |= res["steering_mrad"] + res.pop("steering_bound") >= SATURATION_FRACTION * study.range_mrad
    codes = np.full(len(block), MODEL_CODES["reduced"], np.int8)
    if np.any(near):
        full = evaluate_configs(study, block[near], chunk)
        for k in res:
            res[k][near] = full[k]
        codes[near] = MODEL_CODES["full"]
    return res, codes


def _monte_carlo(study, thetas, done, limit_um, chunk, out, identity, surrogate, progress):
    """The metric and model code of every configuration from ``done`` on, chunk by chunk, each
    chunk appended to the store ``out``; those before ``done`` are read from it."""
    metrics, codes, steer, sat = [], [], [], []
    if done:
        ds = load_sweep(out)
        metrics.append(np.asarray(ds["metric"].values)[:done])
        codes.append(np.asarray(ds["model"].values)[:done])
        if "saturated" in ds:
            sat.append(np.asarray(ds["saturated"].values)[:done].astype(bool))
            steer.append(np.asarray(ds["steering_mrad"].values)[:done])
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(thetas), initial=done, unit="config", desc="sweep", leave=False)
    labels = study.space.labels()
    for start in range(done, len(thetas), chunk):
        block = thetas[start:start + chunk]
        res, model_codes = _chunk_outputs(study, surrogate, block, limit_um, chunk)
        metrics.append(np.asarray(res["metric"]))
        codes.append(model_codes)
        if "saturated" in res:
            sat.append(np.asarray(res["saturated"], bool))
            steer.append(np.asarray(res["steering_mrad"], float))
        if out is not None:
            append_chunk(out, identity, labels, block, res, model_codes)
        if bar is not None:
            bar.update(len(block))
    if bar is not None:
        bar.close()
    metric = np.concatenate(metrics) if metrics else np.zeros(0)
    steering = (np.concatenate(steer), np.concatenate(sat)) if sat else None
    return metric, (np.concatenate(codes) if codes else np.zeros(0, np.int8)), steering


def _reliability_fields(study, sigma, stats: YieldStatistics, response) -> dict:
    """The :class:`SweepResult` fields of FORM, importance sampling (from ``stats``) and the RSS
    stack-up of the linear response ``(r0, J)`` under the laws' standard deviations ``sigma``."""
    f, i = stats.form, stats.importance
    out = dict(form_yield=f.yield_, form_beta=f.beta, form_converged=f.converged)
    if i is not None:
        out.update(is_yield=i.yield_, is_ci95=list(i.ci95), is_samples=i.samples)
    out.update(rss_3sigma_um=rss_stackup(LinearResponse(*response, study.aggregate), sigma).three_sigma_um,
               design_point=misalignment_per_roller(study.space, f.theta_star))
    return out


@dataclasses.dataclass(frozen=True)
class YieldDiscretisation(Result):
    """The discretisation bias of a sweep's yield (:func:`yield_discretisation`).

    **Fields:** ``bias`` the yield on the grid one level finer minus the sweep's, from the
    re-evaluated samples (the others keep their verdict); ``samples`` those re-evaluated: the
    ones whose metric lies nearest the limit, the only ones a small change of the metric can
    turn; ``flipped`` how many changed verdict; ``metric_relative_change`` the median relative
    change of their metric; ``grid``/``grid_fine`` the two grids (:class:`~jaxbelt.accuracy.Grid`,
    ``None`` where not given)."""

    bias: float
    samples: int
    flipped: int
    metric_relative_change: float
    grid: Grid | None
    grid_fine: Grid | None



def yield_discretisation(res: SweepResult, study: Study, fine_model, fine_options: RunOptions,
                         k: int = 16, *, grid: Grid | None = None,
                         grid_fine: Grid | None = None) -> YieldDiscretisation:
    """Re-evaluate the samples of ``res`` whose metric is nearest the limit on
    ``fine_model`` (the same scene one level finer, run with ``fine_options``; the
    metric, components, evaluation time and window those of ``study``) and count the verdicts
    that change: the yield's discretisation bias beside its sampling interval. The samples re-run
    are those within :data:`FLIP_BAND` of the limit — a grid one level finer moves a design
    scene's metric by a few per cent of the limit at most (``benchmarks/design_error_bars.py``), so
    no sample farther out can change its verdict — at most ``k`` of them and at least the
    :data:`MIN_RECHECKED` nearest, which measure the metric's relative change. The samples are the
    sweep's own (``res.configurations``); a steered machine's saturation verdicts are kept. The
    finer grid's aligned reference runs in the same ``vmap`` batch as the samples
    (:func:`jaxbelt.design.study.make_study_at`)."""
    n = res.samples
    if res.configurations is None:
        raise ValueError("yield_discretisation: the sweep's configurations are needed (SweepResult.configurations, "
                         "as run_sweep returns it)")
    thetas = np.asarray(res.configurations)
    values = np.asarray(res.metric_values)
    order = np.argsort(np.abs(values - res.limit_um))
    within = int(np.sum(np.abs(values - res.limit_um) <= FLIP_BAND * res.limit_um))
    pick = order[: min(n, max(MIN_RECHECKED, min(k, within)))]
    limits = study.limits
    _, fine = study_on(fine_model, study, thetas[pick], fine_options, limits=limits)
    fine = on_limit_scale(fine, limits)  # several limits: as the sweep's metric
    before, after = values[pick] <= res.limit_um, fine <= res.limit_um
    rel = np.abs(fine - values[pick]) / np.maximum(np.abs(values[pick]), 1e-12)
    return YieldDiscretisation(
        bias=float((np.sum(after) - np.sum(before)) / n), samples=int(len(pick)), flipped=int(np.sum(before != after)),
        metric_relative_change=float(np.median(rel)) if len(rel) else 0.0, grid=grid, grid_fine=grid_fine)


def run_sweep(study: Study, dist: Distribution, n: int, limit_um: float = 20.0, seed: int = 0,
              chunk: int = 64, out=None, rom: str = "off", with_form: bool = True, progress: bool = False,
              scene: str = "", importance_samples: int = 200, rom_method: str = "response",
              linear: LinearDeviation | None = None) -> SweepResult:
    """Monte-Carlo yield of ``study`` under ``dist`` (module docstring).

    **Arguments:** ``n`` samples (the first ``n`` of ``seed``'s sequence); ``limit_um``; ``chunk``
    configurations per batch (and per stored chunk); ``out`` the Zarr store (a rerun resumes);
    ``rom`` ``"off"`` | ``"auto"``; ``rom_method`` the surrogate's reduced model with
    ``rom="auto"`` (:func:`~jaxbelt.design.surrogate.fit_surrogate`'s ``method``: ``"response"``
    or ``"pod"``); ``with_form`` also the RSS stack-up, FORM and importance sampling
    (``importance_samples``); ``progress`` a progress bar; ``scene`` the scene's name, part of
    the store's identity; ``linear`` the study's :class:`~jaxbelt.design.linearisation.LinearDeviation`
    (``make_study(..., jacobian=True)``): FORM, the RSS stack-up and a steady study's surrogate
    read the linear response from it instead of a run.

    **Returns:** a :class:`SweepResult`."""
    t0 = time.perf_counter()
    _check(n, limit_um, rom, rom_method)
    limits, t_eval, range_mrad = study.limits, study.t_eval, study.range_mrad
    check_distribution(dist, study)
    thetas, distribution, sigma = sample_configurations(dist, n, seed), dist.to_dict(), dist.sigma
    if limits and not math.isclose(float(limit_um), limits[0][1]):
        raise ValueError(f"limit_um = {limit_um}: a study with several limits is judged on the scale of its first "
                         f"limit ({limits[0][0]} ≤ {limits[0][1]:g}); pass that")
    identity = _identity(study, t_eval, limits, distribution, limit_um, seed, scene)
    done = min(open_sweep(out, identity), n) if out is not None else 0
    surrogate, rom_use = None, ReducedModelUse(used=False)
    if rom == "auto" and study.steered and rom_method == "pod":
        rom_use = ReducedModelUse(used=False, reason=ROM_STEERED)
    elif rom == "auto" and done < n:
        surrogate, rom_use = _surrogate(study, dist, limit_um, seed, rom_method, linear)
    metric, code, steering = _monte_carlo(study, thetas, done, limit_um, chunk, out, identity, surrogate, progress)
    extra = {}
    if steering is not None:
        extra.update(saturated=int(np.sum(steering[1])), range_mrad=range_mrad,
                     steering_max_mrad=float(np.max(steering[0])) if len(steering[0]) else 0.0)
    if rom_use.used and rom_use.validation.n_validation:
        # indicative: the validation's full runs (their compilation included) per configuration
        per_full = rom_use.validation.validation_s / rom_use.validation.n_validation
        extra["speedup_estimate"] = (n - done) * per_full / max(time.perf_counter() - t0, 1e-9)
    # FORM and the RSS stack-up read the linear response; importance samples are evaluated as the
    # Monte Carlo's are (the surrogate, and in full where it cannot decide)
    response = response_jacobian(study, linear=linear) if with_form else None
    metric_of = None if surrogate is None else \
        (lambda th: _chunk_outputs(study, surrogate, th, limit_um, chunk)[0]["metric"])
    stats = yield_statistics(study, dist, limit_um, metric, None if steering is None else steering[1],
                             response=response, importance_samples=importance_samples, seed=seed + 1, chunk=chunk,
                             metric_of=metric_of)
    passed = stats.passed
    if with_form:
        extra.update(_reliability_fields(study, sigma, stats, response))
    wall = time.perf_counter() - t0
    return SweepResult(
        metric=study.metric, limit_um=float(limit_um), samples=int(n), seed=int(seed),
        yield_=passed / n, ci95=list(stats.ci95), passed=passed,
        # the surrogate's training and validation runs are full runs too, used or not
        full_runs=int(np.sum(code == MODEL_CODES["full"])) + rom_use.validation_runs,
        reduced_runs=int(np.sum(code == MODEL_CODES["reduced"])), rom=rom_use, metric_values=metric,
        wall_s=wall, configs_per_s=(n - done) / wall,
        limits=tuple(MetricLimit(k, v, metric_unit(k)) for k, v in limits) or None, unit=study.unit,
        configurations=thetas, **extra)
