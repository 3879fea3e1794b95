"""Sensitivities of a metric to every roller misalignment component, through the whole run.

The gradient is reverse-mode AD through the time loop (solve → transport, ``lax.scan``): the
step's linear solve carries an adjoint that reuses its structured factors and the scan is
checkpointed (see :mod:`jaxbelt.linalg.bordered` and :mod:`jaxbelt.timeloop`). The Jacobian
of the response vector (the tracer deviations the metric aggregates) uses forward mode when
there are fewer parameters than responses (``jax.jacfwd``: one tangent per parameter, batched),
reverse mode otherwise.

Units: metric in µm; gradient in µm/mm (translations) and µm/mrad (rotations).
"""

from __future__ import annotations

import dataclasses
import time

import jax
import jax.numpy as jnp
import numpy as np

from .metrics import response_from_deviation
from .records import ComponentGradient, RollerSensitivity, StructuralZero, sensitivity_per_roller
from .linearisation import LinearDeviation
from .study import Study, metric_value, response
from ..infra.programs import stored_jit
from ..infra.results import Result, in_metric_unit


KINK_UM = 1e-6  # a metric at or below this is at its kink r = 0


def _zeros(study: Study):
    return jnp.zeros(study.space.size, study.base.dtype)


@stored_jit
def _value(study, theta):
    return metric_value(study, theta)


@stored_jit
def _value_and_grad(study, theta):
    return jax.value_and_grad(lambda t: metric_value(study, t, smooth=True))(theta)


@stored_jit
def _response_and_jacobian(study, theta, forward: bool):
    """``(r, J)`` from one differentiated run: the response rides along as the Jacobian's auxiliary
    output, the primal the tangents (or the cotangents) are taken at — not a second run."""
    jac = jax.jacfwd if forward else jax.jacrev
    J, r = jac(lambda t: (response(study, t),) * 2, has_aux=True)(theta)
    return r, J


@stored_jit
def _response_and_jacobian_from_linear(study, linear: LinearDeviation):
    """``(r, J)`` at ``θ = 0`` from the linear deviations ``linear`` (the chain rule through the
    response alone, no run)."""

    def r(theta):
        out = response_from_deviation(study, *linear.deviation(theta))
        return out, out

    J, r0 = jax.jacfwd(r, has_aux=True)(_zeros(study))
    return r0, J


def _best_time(f, repeat: int):
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = jax.block_until_ready(f())
        best = min(best, time.perf_counter() - t0)
    return out, best


def value_and_gradient(study: Study, theta=None):
    """Metric (µm) and its gradient (P,) at ``theta`` (default: the scene's own misalignment).
    ``lateral_peak`` is differentiated through its smooth version."""
    theta = _zeros(study) if theta is None else jnp.asarray(theta, study.base.dtype)
    return _value_and_grad(study, theta)


def response_jacobian(study: Study, theta=None, mode: str = "auto", linear: LinearDeviation | None = None):
    """``(r0, J)``: the response ``r`` (n_r,) at ``theta`` and ``J = ∂r/∂θ`` (n_r, P), µm per
    mm / mrad. ``mode``: ``"forward"``, ``"reverse"`` or ``"auto"`` (forward when P ≤ n_r).
    ``linear``: the study's :class:`~jaxbelt.design.linearisation.LinearDeviation` (from
    ``make_study(..., jacobian=True)``), read instead of a run; it holds ``θ = 0`` only, so
    ``theta`` is then not given."""
    if mode not in ("auto", "forward", "reverse"):
        raise ValueError(f"mode = {mode!r}: one of auto, forward, reverse")
    if linear is not None:
        if theta is not None:
            raise ValueError("theta: the linear deviations hold θ = 0 only; pass theta or linear, not both")
        r, J = _response_and_jacobian_from_linear(study, linear)
        return np.asarray(r), np.asarray(J)
    theta = _zeros(study) if theta is None else jnp.asarray(theta, study.base.dtype)
    n_r = jax.eval_shape(lambda t: response(study, t), theta).shape[0]
    forward = mode == "forward" or (mode == "auto" and study.space.size <= n_r)
    r, J = _response_and_jacobian(study, theta, forward)
    return np.asarray(r), np.asarray(J)


@dataclasses.dataclass(frozen=True)
class SensitivityReport(Result):
    """A metric and its gradient w.r.t. every misalignment component (:func:`sensitivity_report`).

    **Fields:** ``metric``; ``value_um`` the metric in ``unit`` (µm; mrad for ``steering_max``, µm/s for ``walk_rate``),
    the gradients in ``unit`` per mm / mrad (the JSON keys of the value and the gradients name
    ``unit``: ``value_mrad``); ``t_eval_s``;
    ``parameters`` one :class:`~jaxbelt.design.records.ComponentGradient` per varied component;
    ``gradient`` ``{roller: RollerSensitivity}`` (:class:`~jaxbelt.design.records.RollerSensitivity`,
    0 for components that are not parameters); ``structural_zero`` the components that cannot
    vary (:class:`~jaxbelt.design.records.StructuralZero`); ``at_kink`` whether the metric sat at its kink ``r = 0`` (then
    the gradients are one-sided slopes); ``forward_s``, ``gradient_s`` the best wall times of a
    forward run and of the gradient, ``compile_s`` their first calls' (compilation included).
    """

    metric: str
    value_um: float = in_metric_unit()
    t_eval_s: float
    parameters: tuple[ComponentGradient, ...]
    gradient: dict[str, RollerSensitivity]
    structural_zero: tuple[StructuralZero, ...]
    at_kink: bool
    forward_s: float
    gradient_s: float
    compile_s: float
    unit: str = "µm"



def sensitivity_report(study: Study, theta=None, repeat: int = 3) -> SensitivityReport:
    """Value and gradient at ``theta`` with their wall times (compilation excluded, best of
    ``repeat``), per roller and component: the ``jaxbelt sensitivity`` report
    (:class:`SensitivityReport`).

    Every metric is a norm of the response ``r``, which has a kink where ``r = 0`` — the aligned
    machine itself. There (metric ≤ 1e-6 µm, ``at_kink``) the reverse-mode gradient is
    round-off, so the report gives the one-sided slope of the metric along each component
    instead, from the forward-mode Jacobian: ``‖J_k‖/√n`` (RMS) or ``max_i |J_ik|`` (max-type),
    the same for + and − (timings are still those of the reverse-mode gradient).
    """
    theta = _zeros(study) if theta is None else jnp.asarray(theta, study.base.dtype)
    t0 = time.perf_counter()
    jax.block_until_ready(_value(study, theta))
    jax.block_until_ready(_value_and_grad(study, theta))
    compile_s = time.perf_counter() - t0
    value, forward_s = _best_time(lambda: _value(study, theta), repeat)
    (_, grad), gradient_s = _best_time(lambda: _value_and_grad(study, theta), repeat)
    at_kink = float(value) <= KINK_UM
    if at_kink:  # every metric is a norm of r: at r = 0 the gradient is round-off; report the slopes
        _, J = response_jacobian(study, theta)
        grad = np.sqrt(np.mean(J**2, axis=0)) if study.aggregate == "rms" else np.abs(J).max(axis=0)
    sp = study.space
    structural = tuple(StructuralZero(f"{sp.roller_names[j]}:{c}", why) for (j, c), why in sp.structural
                       if not why.startswith("not modelled"))
    return SensitivityReport(
        metric=study.metric, value_um=float(value), t_eval_s=study.t_eval,
        parameters=tuple(ComponentGradient(lab, unit, float(g))
                         for lab, unit, g in zip(sp.labels(), sp.units(), np.asarray(grad))),
        gradient=sensitivity_per_roller(sp, np.asarray(grad), study.unit), structural_zero=structural, at_kink=at_kink,
        forward_s=forward_s, gradient_s=gradient_s, compile_s=compile_s, unit=study.unit)
