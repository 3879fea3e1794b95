"""The largest safe tolerance box, verified by full runs.

A *tolerance box* is a vector of half-widths ``h`` (P,) ≥ 0 around the scene's own misalignment
within which every configuration keeps the metric at or below the limit. It is optimised on the
linear model of the response (:mod:`jaxbelt.design.linear_box`: the worst case over a box, the
largest box under the limit, the RSS stack-up). The box is **verified by full runs** at the worst
corners and a few random ones. The first box verified is the optimum scaled, under the linear
model, onto the middle of the accepted band (0.985 × limit), so that the model's small
nonlinearity does not push the first verification out of it; if the verified worst case is not
within ``[0.97, 1.0] × limit`` the box is scaled (secant iteration on a uniform factor) and
verified again.

**Several limits at once** (``limits``, e.g. ``{"longitudinal_max": 20, "steering_max": 3}``
beside a max-type study metric): every metric's response is divided by its limit and stacked
(:func:`jaxbelt.design.study.with_limits`), so one max-type constraint holds all of them; it is
carried on the scale of the study's own limit (``ratio × limit_um``), so ``worst_case_um``, the
verification values and the plot read as before, and ``limits`` reports each metric in its own
unit, its predicted and verified worst case, and which one *binds* (the largest verified ratio).
On a steered machine the steering range is such a limit: a box within it never saturates the
actuator (the PI law is linear until it clips, so the box machinery applies).
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from ..accuracy import Grid
from ..infra.results import Result, in_metric_unit, json_fields, to_json, unit_field
from ..misalignment import ROTATIONS, TRANSLATIONS, ParameterSpace
from ..timeloop import RunOptions
from .linear_box import H_MAX, LinearResponse, optimise_box, rss_stackup, worst_case, worst_corners
from .linearisation import LinearDeviation
from .metrics import (METRICS, aggregate, aligned_values, limit_values_from_deviation, metric_unit, on_limit_scale,
                      response_sizes)
from .records import RollerMisalignment, misalignment_per_roller
from .configurations import at_configurations, evaluate_metric
from .study import Study, study_on, with_limits
from .sensitivity import response_jacobian

CAP_FRACTION = 0.999  # a half-width at this fraction of h_max or above counts as capped (not felt)

# ----------------------------------------------------------------------------- the study


def _shares(lin: LinearResponse, h, W: float) -> np.ndarray:
    """How much each component contributes to the worst case, at every *active* constraint
    (within 1 % of ``W``): the parts ``|J_ik| h_k`` of an active row (max-type metrics; for
    RMS the row with the largest deviation at an active corner), normalised per constraint,
    then the largest share over the active constraints."""
    if lin.kind == "max":
        rows = np.flatnonzero(np.abs(lin.r0) + np.abs(lin.J) @ h >= 0.99 * W)
    else:
        signs, vals = worst_corners(lin, h, 64)
        rows = [np.argmax(np.abs(lin.r0 + lin.J @ (s * h))) for s, v in zip(signs, vals) if v >= 0.99 * W]
    share = np.zeros(len(h))
    for i in rows:
        c = np.abs(lin.J[i]) * h
        share = np.maximum(share, c / max(c.sum(), 1e-300))
    return share


@dataclasses.dataclass(frozen=True)
class VerificationRun(Result):
    """One full run of a box's verification (:func:`tolerance_box`). **Fields:** ``kind``
    ``"worst corner"`` or ``"random corner"``; ``corner`` the configuration run, ``{roller:
    RollerMisalignment}`` (mm / mrad around the scene's own misalignment); ``predicted_um`` the
    linear model's metric there; ``full_um`` the full run's (both in ``unit``, the box's; with
    several limits both on the scale of ``limit_um``: the largest ratio to its limit times
    ``limit_um``); ``full_by_limit`` with several limits ``{metric: value}``, each in its metric's
    own unit, else ``None`` (left out of :meth:`to_dict`)."""

    kind: str
    corner: dict[str, RollerMisalignment]
    predicted_um: float = in_metric_unit()
    full_um: float = in_metric_unit()
    full_by_limit: dict[str, float] | None = None
    unit: str = unit_field()

    def to_dict(self) -> dict:
        """The run as JSON-able data, ``full_by_limit`` only with several limits."""
        out = json_fields(self)
        if self.full_by_limit is None:
            del out["full_by_limit"]
        return to_json(out)


@dataclasses.dataclass(frozen=True)
class LimitCheck(Result):
    """One limit of a box with several (module docstring), each value in the metric's own
    ``unit``. **Fields:** ``metric``; ``limit``; ``unit``; ``predicted_worst`` the linear model's
    worst case over the box; ``worst_case`` the verified one (full runs); ``ratio`` verified worst
    over limit; ``binds`` whether this limit has the largest ratio."""

    metric: str
    limit: float
    unit: str
    predicted_worst: float
    worst_case: float
    ratio: float
    binds: bool


@dataclasses.dataclass(frozen=True)
class ToleranceBox(Result):
    """The verified tolerance box of a study (:func:`tolerance_box`).

    **Fields:** ``metric``, ``limit_um``, ``t_eval_s`` the question; ``half_widths`` (P,) in
    ``units`` (mm / mrad) of the components ``labels``, around the scene's own misalignment;
    ``box`` the same per roller, ``{name: RollerMisalignment}``
    (:class:`~jaxbelt.design.records.RollerMisalignment`); ``share`` (P,) each component's largest share of an active constraint;
    ``predicted_worst_um`` the linear model's worst case; ``worst_case_um`` the verified one
    (full runs); ``verified`` whether that lies in ``[0.97, 1] × limit``; ``binding`` the
    components by share, largest first; ``unconstrained`` those capped at ``h_max`` (not felt);
    ``verification`` one :class:`VerificationRun` per full run of the last iteration; ``iterations``; ``rss_um`` the RSS stack-up with ``σ = h/3``;
    ``jacobian_um`` (n_r, P) and ``response0_um`` (n_r,) the linear response ``r0 + J θ``;
    ``limits`` with several limits (module docstring) one :class:`LimitCheck` per limit, else
    ``()``; ``binding_limit`` the metric whose limit
    binds (the study's metric with a single limit); ``unit`` the unit of ``limit_um``, the worst
    cases, the stack-up and the linear response (the metric's: µm, mrad or µm/s; the first
    limit's with several limits; the JSON keys of those fields name it,
    :func:`jaxbelt.infra.results.unit_key`). With several limits ``worst_case_um``,
    ``predicted_worst_um``, the verification values and the linear response are the largest ratio
    to its limit times ``limit_um``, and every verification run has ``full_by_limit``.
    """

    metric: str
    limit_um: float = in_metric_unit()
    t_eval_s: float
    half_widths: np.ndarray
    units: list
    labels: list
    box: dict[str, RollerMisalignment]
    share: np.ndarray
    predicted_worst_um: float = in_metric_unit()
    worst_case_um: float = in_metric_unit()
    verified: bool
    binding: list
    unconstrained: list
    verification: tuple[VerificationRun, ...]
    iterations: int
    rss_um: float = in_metric_unit()
    jacobian_um: np.ndarray = in_metric_unit()
    response0_um: np.ndarray = in_metric_unit()
    limits: tuple[LimitCheck, ...] = ()
    binding_limit: str = ""
    corners: np.ndarray | None = None  # (m, P) the verified worst corners, as parameter vectors
    limit_names: tuple | None = None  # ((metric, limit), ...) with several limits
    unit: str = "µm"

    def to_dict(self) -> dict:
        """The box as JSON-able data (``jaxbelt tolerance --json``): the scalar and table fields
        (metric values keyed by ``unit``) and ``half_widths`` as ``[{"component", "half_width",
        "unit", "share"}]``."""
        out = json_fields(self, ("metric", "limit_um", "t_eval_s", "box", "worst_case_um", "predicted_worst_um",
                                 "verified", "binding", "unconstrained", "iterations", "rss_um", "limits",
                                 "binding_limit", "unit"))
        out["verification"] = [row.to_dict() for row in self.verification]
        out["half_widths"] = [{"component": lab, "half_width": float(h), "unit": u, "share": float(s)}
                              for lab, h, u, s in zip(self.labels, self.half_widths, self.units, self.share)]
        return to_json(out)


def _verify(lin, h_lin, felt, limit_um, evaluate_many, corners_random, n_corners, max_iter, space, names, unit):
    """Full runs at the worst and the random corners, the box scaled (uniform factor, secant)
    until the verified worst case lies in ``[0.97, 1] × limit``. ``evaluate_many`` returns the
    metric (m,), or with several limits (``names``: ``((metric, limit), ...)``) each limit's
    value in its own unit (m, n_limits). **Returns:** ``(h, worst, table, iterations)``."""
    target, history, table = 0.985 * limit_um, [], []
    floor = float(aggregate(lin.kind, jnp.asarray(lin.r0)))
    # the first box aims at the middle of the accepted band, not its edge: the linear model puts
    # h_lin's worst case on the limit, and the excess over the floor scales with a uniform factor
    s = (target - floor) / max(limit_um - floor, 1e-12) if floor < target else 1.0
    n_random = len(corners_random)
    for _ in range(max_iter):
        h = np.where(felt, s * h_lin, h_lin)
        signs, pred = worst_corners(lin, h, n_corners)
        corners = np.concatenate([signs, corners_random])
        values = np.asarray(evaluate_many(corners * h))
        full = on_limit_scale(values, names)
        pred_all = np.concatenate([pred, [lin.metric(c * h) for c in corners_random]])
        kinds = ["worst corner"] * len(signs) + ["random corner"] * n_random
        by_limit = [{n: float(x) for (n, _), x in zip(names, v)} for v in values] if names else [None] * len(full)
        table = tuple(VerificationRun(k, misalignment_per_roller(space, c * h), float(p), float(f), b, unit)
                      for k, c, p, f, b in zip(kinds, corners, pred_all, full, by_limit))
        worst = float(np.max(full))
        history.append((s, worst))
        if 0.97 * limit_um <= worst <= limit_um:
            break
        if len(history) == 1:  # first correction: assume the excess over the floor scales with s
            s = s * (target - floor) / max(worst - floor, 1e-12)
        else:  # secant on the uniform factor
            (s0, w0), (s1, w1) = history[-2], history[-1]
            s = s1 + (target - w1) * (s1 - s0) / (w1 - w0) if w1 != w0 else s1 * target / w1
        s = max(s, 1e-6)
    return h, worst, table, len(history), signs * h


def _limit_values_batch(study: Study, thetas):
    """Every limited metric (:func:`~jaxbelt.design.study.limit_values`) at each row of ``thetas``."""
    return at_configurations(study, thetas, limit_values_from_deviation)


def _per_limit(lin, h, names, sizes, limit_um, table):
    """The ``limits`` table of a box with several limits and the binding metric's name."""
    rows, start = [], 0
    for (name, lim), n in zip(names, sizes):
        block = slice(start, start + n)
        start += n
        pred = float(np.max(np.abs(lin.r0[block]) + np.abs(lin.J[block]) @ h)) * lim / limit_um
        full = max(row.full_by_limit[name] for row in table)
        rows.append(LimitCheck(metric=name, limit=float(lim), unit=metric_unit(name), predicted_worst=pred,
                               worst_case=full, ratio=full / lim, binds=False))
    binding = max(rows, key=lambda r: r.ratio)
    return tuple(dataclasses.replace(r, binds=r is binding) for r in rows), binding.metric


def tolerance_box(study: Study, limit_um: float = 20.0, weights=None, h_max: float = H_MAX,
                  n_random: int = 4, n_corners: int = 4, max_iter: int = 6, seed: int = 0,
                  evaluate_many=None, limits: dict | None = None,
                  linear: LinearDeviation | None = None) -> ToleranceBox:
    """The largest weighted tolerance box keeping ``study``'s metric ≤ ``limit_um``, verified by
    full runs (module docstring).

    **Arguments:** ``weights`` (P,) cost weights (default 1); ``h_max`` cap of a half-width
    (mm / mrad); ``n_corners`` worst corners and ``n_random`` random corners verified per
    iteration; ``evaluate_many(thetas (m, P)) -> metrics (m,)`` runs the full model (default: a
    ``vmap`` of :func:`jaxbelt.design.study.metric_value`; with ``limits``, each limit's value
    (m, n_limits)); ``limits`` further limits held at the same time, ``{metric: limit}`` in each
    metric's unit (max-type metrics; the study's metric must be one too); ``linear`` the study's
    :class:`~jaxbelt.design.linearisation.LinearDeviation` (``make_study(..., jacobian=True)``), the
    linear response read from it instead of a run.

    **Returns:** a :class:`ToleranceBox`.
    """
    if not (np.isfinite(limit_um) and limit_um > 0):
        raise ValueError(f"limit_um = {limit_um}: must be a positive number")
    names = None
    if limits:
        if METRICS[study.metric].aggregate != "max":
            raise ValueError(f"limits: several limits at once need a max-type metric (not {study.metric})")
        names = ((study.metric, float(limit_um)),) + tuple((k, float(v)) for k, v in limits.items())
        work = with_limits(study, names)
    else:
        work = study
    if evaluate_many is None:
        def evaluate_many(thetas):
            if names:
                return np.asarray(_limit_values_batch(work, jnp.asarray(thetas, work.base.dtype)))
            return evaluate_metric(study, thetas)

    sp = study.space
    r0, J = response_jacobian(work, linear=linear)
    # with several limits the response is already on the scale of limit_um (the first limit)
    lin = LinearResponse(r0, J, work.aggregate)
    h_lin = optimise_box(lin, limit_um, weights, h_max)
    # not felt: no response at all, or a half-width the optimiser left at the cap (within 0.1 %): such a
    # component is reported as unconstrained, never as a tolerance
    felt = np.any(J != 0, axis=0) & (h_lin < CAP_FRACTION * h_max)
    rand = np.random.default_rng(seed).choice([-1.0, 1.0], size=(n_random, len(h_lin)))  # the same in every iteration
    h, worst, table, iterations, thetas = _verify(lin, h_lin, felt, limit_um, evaluate_many, rand, n_corners, max_iter, sp,
                                                  names, study.unit)
    W = worst_case(lin, h)
    per_limit, binding_limit = ((), study.metric) if not names else _per_limit(
        lin, h, names, response_sizes(work), limit_um, table)
    share = _shares(lin, h, W)
    labels = sp.labels()
    binding = [labels[k] for k in np.argsort(-share) if felt[k] and share[k] > 0]
    return ToleranceBox(
        metric=study.metric, limit_um=float(limit_um), t_eval_s=study.t_eval,
        half_widths=h, units=sp.units(), labels=labels,
        box=misalignment_per_roller(sp, h),
        share=share, predicted_worst_um=W, worst_case_um=worst,
        verified=bool(0.97 * limit_um <= worst <= limit_um),
        binding=binding, unconstrained=[labels[k] for k in range(len(h)) if not felt[k]],
        verification=table, iterations=iterations,
        rss_um=rss_stackup(lin, h / 3.0).three_sigma_um, jacobian_um=J, response0_um=r0,
        limits=per_limit, binding_limit=binding_limit, corners=thetas, limit_names=names, unit=study.unit)


NEAR_WORST = 1e-3  # corners run on the finer grid: within this fraction of the worst excess over the floor
# (an optimal box has several corners near the limit; the finer grid moves them alike, by the grid's
# systematic error, so the worst one stands for them: an error bar needs its size, not a fourth digit)


@dataclasses.dataclass(frozen=True)
class BoxDiscretisation(Result):
    """The discretisation uncertainty of a tolerance box (:func:`box_discretisation`).

    **Fields:** ``worst_case_um``/``worst_case_fine_um`` the largest metric over the box's
    worst corners on the box's grid and (those within :data:`NEAR_WORST` of it) on the grid one
    level finer (on the scale of
    ``limit_um`` with several limits); ``floor_um``/``floor_fine_um`` the metric of the scene's
    own misalignment (no tolerance) on both; ``half_width_relative_change`` the relative change
    of every half-width the finer grid asks for (the box scaled until its worst corner is back at
    the verified level, the excess over the floor taken as linear in the scale);
    ``half_width_uncertainty`` (P,) its size per half-width, in their units; ``grid``/``grid_fine``
    the two grids (:class:`~jaxbelt.accuracy.Grid`, ``None`` where not given); ``runs`` the full runs made on the finer grid (its aligned reference included);
    ``unit`` the unit of the metric values (the box's; named by the JSON keys)."""

    worst_case_um: float = in_metric_unit()
    worst_case_fine_um: float = in_metric_unit()
    floor_um: float = in_metric_unit()
    floor_fine_um: float = in_metric_unit()
    half_width_relative_change: float
    half_width_uncertainty: np.ndarray
    grid: Grid | None
    grid_fine: Grid | None
    runs: int
    unit: str = unit_field()



def _box_floor(box: ToleranceBox, kind: str) -> float:
    """The box's measure at the scene's own misalignment on the box's grid, from the linear
    response's ``r0`` (the full run at ``θ = 0`` the Jacobian was taken at)."""
    return float(aggregate(kind, jnp.asarray(box.response0_um)))


def box_discretisation(box: ToleranceBox, study: Study, fine_model, fine_options: RunOptions, *,
                       grid: Grid | None = None, grid_fine: Grid | None = None) -> BoxDiscretisation:
    """The box's worst corners (those of the last verification within :data:`NEAR_WORST` of the
    worst one's excess over the floor) and the scene's own misalignment on ``study``'s grid and on ``fine_model``'s — the same scene one level finer, run with
    ``fine_options`` (the metric, components, evaluation time and window those of ``study``)
    — and the half-widths' relative change that follows (:class:`BoxDiscretisation`).

    On the box's own grid the values are the box's: its last verification's full runs at the
    worst corners and the response ``r0`` at the scene's misalignment. The finer grid runs them
    as one batch with its aligned reference (:func:`jaxbelt.design.study.make_study_at`);
    where the scene is aligned (its own misalignment zero) the run at ``θ = 0`` is that
    reference itself, read from it (:func:`jaxbelt.design.metrics.aligned_values`), not
    repeated."""
    worst_rows = np.array([row.full_um for row in box.verification if row.kind == "worst corner"])
    floor, worst = _box_floor(box, study.aggregate), float(np.max(worst_rows))
    # the corners that can be the worst on the finer grid: within NEAR_WORST of the excess over the floor
    corners = box.corners[worst_rows >= worst - NEAR_WORST * max(worst - floor, 0.0)]
    aligned_scene = not np.any(np.asarray(study.base))
    thetas = corners if aligned_scene else np.concatenate([np.zeros((1, corners.shape[1])), corners])
    fine_study, values = study_on(fine_model, study, thetas, fine_options, limits=box.limit_names or ())
    fine = on_limit_scale(values, box.limit_names)
    if aligned_scene:
        metric, per_limit = aligned_values(fine_study)
        floor_f = float(metric) if per_limit is None else float(
            on_limit_scale(per_limit[None], box.limit_names)[0])
        worst_f = float(np.max(fine))
    else:
        floor_f, worst_f = float(fine[0]), float(np.max(fine[1:]))
    scale = (worst - floor_f) / (worst_f - floor_f) if worst_f > floor_f else 1.0
    return BoxDiscretisation(
        worst_case_um=worst, worst_case_fine_um=worst_f, floor_um=floor, floor_fine_um=floor_f,
        half_width_relative_change=float(scale - 1.0),
        half_width_uncertainty=np.abs(scale - 1.0) * np.asarray(box.half_widths),
        grid=grid, grid_fine=grid_fine, runs=len(thetas) + 1, unit=box.unit)


def weights_from_dict(data: dict, space: ParameterSpace) -> np.ndarray:
    """Cost weights (P,) from a weights table (the ``--weights`` TOML file); default 1.

    Format: ``[roller."NAME"]`` with ``translation = [wx, wy, wz]`` and/or ``rotation = [wx, wy,
    wz]``, positive numbers; a larger weight makes a component costlier to tighten, so it gets a
    wider share of the budget. Raises ``ValueError`` naming the key and value.
    """
    w = np.ones(space.size)
    if set(data) - {"roller"}:
        raise ValueError(f"weights file: unknown table(s) {sorted(set(data) - {'roller'})} (only [roller.\"NAME\"])")
    for name, table in data.get("roller", {}).items():
        if name not in space.roller_names:
            raise ValueError(f"roller.{name!r}: no roller of that name (rollers: {', '.join(space.roller_names)})")
        if not isinstance(table, dict):
            raise ValueError(f"roller.{name!r}: must be a table")
        j = space.roller_names.index(name)
        for group, vals in table.items():
            if group not in ("translation", "rotation"):
                raise ValueError(f"roller.{name!r}.{group}: unknown key (translation or rotation)")
            if not isinstance(vals, list) or len(vals) != 3 or not all(isinstance(v, (int, float)) for v in vals):
                raise ValueError(f"roller.{name!r}.{group} = {vals!r}: must be a list of 3 numbers")
            for k, v in enumerate(vals):
                if not (np.isfinite(v) and v > 0):
                    raise ValueError(f"roller.{name!r}.{group}[{k}] = {v}: must be a positive number")
                comp = (TRANSLATIONS if group == "translation" else ROTATIONS)[k]
                if (j, comp) in space.entries:
                    w[space.entries.index((j, comp))] = float(v)
    return w
