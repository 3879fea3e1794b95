"""Belt-position metrics of a tolerance study, in µm, relative to the aligned machine.

Every metric compares a misaligned run with the *aligned* run of the same scene (every
misalignment zero, :func:`jaxbelt.misalignment.aligned`), tracer by tracer and step by step,
so the static stretching of the belt by its pre-tension and drive does not count. With
``d_u``, ``d_v`` (steps, tracers) the longitudinal and lateral tracer deviations in µm and
``k`` the evaluation step (``t_eval``):

| metric | definition | response ``r`` | aggregate |
|---|---|---|---|
| ``lateral_rms`` | $\\sqrt{\\tfrac1n \\sum_i d_v[k, i]^2}$ | ``d_v[k]`` (n_tr,) | RMS |
| ``lateral_max`` | $\\max_i \\lvert d_v[k, i]\\rvert$ | ``d_v[k]`` | max-abs |
| ``longitudinal_rms`` | $\\sqrt{\\tfrac1n \\sum_i d_u[k, i]^2}$ | ``d_u[k]`` | RMS |
| ``lateral_peak`` | $\\max_{i,\\,k' \\in W} \\lvert d_v[k', i]\\rvert$, ``W`` the last ``window`` fraction (10 %) of ``[0, t_eval]`` | ``d_v[W]`` flattened | max-abs |
| ``walk_rate`` | µm/s: least-squares slope of $\\bar d_v(t) = \\tfrac1n\\sum_i d_v(t, i)$ over the second half of ``[0, t_eval]`` (meaningful with ``lateral_transport = true``) | the slope (1,) | max-abs |

The *response* ``r(θ)`` is the vector whose aggregate is the metric; it is nearly linear in the
misalignments, which is what the tolerance box and FORM use (``metric = agg(r)``).
``lateral_peak`` has a smooth version for gradients, the log-sum-exp soft maximum
$\\tau \\log \\sum e^{|r|/\\tau}$ (``smooth=True``, ``τ = 0.05`` µm by default: it exceeds the hard
maximum by at most ``τ log(len r)``).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..integrators import AbstractIntegrator, make_solver
from ..misalignment import ParameterSpace, aligned, apply, parameter_space
from ..model import BeltModel
from ..timeloop import simulate

M_TO_UM = 1e6
METRICS = {
    "lateral_rms": ("rms", True, "RMS over the tracers of the lateral deviation at t_eval, µm"),
    "lateral_max": ("max", True, "largest |lateral deviation| over the tracers at t_eval, µm"),
    "longitudinal_rms": ("rms", False, "RMS over the tracers of the longitudinal deviation at t_eval, µm"),
    "lateral_peak": ("max", True, "largest |lateral deviation| over tracers and the last 10 % of the run, µm"),
    "walk_rate": ("max", True, "|slope| of the mean lateral deviation over the second half of the run, µm/s"),
}
SMOOTH_TAU_UM = 0.05


class Study(eqx.Module):
    """One tolerance question on one model: the metric, its evaluation time, the varied
    components and the aligned reference run. Build with :func:`make_study`.

    **Fields:** ``model``; ``integrator`` the solver of every run; ``dt`` the time step, s (an
    array: traced, so studies at other time steps share compiled programs); ``ref_u``, ``ref_v``
    (n_steps, n_tr) tracer displacements of the aligned run, m, every step recorded (``ref_v``
    ``None`` in 1D); ``base`` (q,) the scene's own misalignment around which ``theta`` is
    measured; ``space`` the varied components; ``metric``; ``n_steps`` the run length (the
    evaluation step); ``window`` the steps of ``lateral_peak``'s window.
    """

    model: BeltModel
    integrator: AbstractIntegrator
    dt: jax.Array
    ref_u: jax.Array
    ref_v: jax.Array | None
    base: jax.Array
    space: ParameterSpace = eqx.field(static=True)
    metric: str = eqx.field(static=True)
    n_steps: int = eqx.field(static=True)
    window: int = eqx.field(static=True)

    @property
    def aggregate(self) -> str:
        return METRICS[self.metric][0]

    @property
    def t_eval(self) -> float:
        """The evaluation time ``n_steps × dt``, s (concrete studies only)."""
        return self.n_steps * float(self.dt)

    def configured(self, theta) -> BeltModel:
        """The model at design vector ``theta`` (P,), mm / mrad around the scene's misalignment."""
        return apply(self.model, self.space, theta, self.base)


def make_study(model: BeltModel, metric: str = "lateral_rms", t_eval: float | None = None, *, dt,
               n_steps: int | None = None, components=None, integrator: AbstractIntegrator | None = None,
               window_fraction: float = 0.1) -> Study:
    """Set up a study: validate the metric and time, select the components, run the aligned
    reference once.

    **Arguments:** ``metric`` (one of :data:`METRICS`); ``t_eval`` evaluation time in s, rounded
    to whole steps of ``dt``; ``dt`` the time step, s; ``n_steps`` the evaluation step when
    ``t_eval`` is not given (a scene's ``RunOptions.n_steps``: its ``t_end``); ``components`` as
    in :func:`jaxbelt.misalignment.parameter_space`; ``integrator`` the solver (default
    :func:`jaxbelt.make_solver`'s; a scene's is ``RunOptions.solver``); ``window_fraction`` of
    ``[0, t_eval]`` for ``lateral_peak``.

    ``jaxbelt.RunOptions`` holds a scene's ``dt``, ``n_steps`` and solver:
    ``make_study(model, metric, dt=opts.dt, n_steps=opts.n_steps, integrator=opts.solver)``.
    """
    if metric not in METRICS:
        raise ValueError(f"metric = {metric!r}: unknown (one of {', '.join(METRICS)})")
    if METRICS[metric][1] and model.kind != "2d":
        raise ValueError(f"metric = {metric!r}: a lateral metric needs a 2D scene (this one is {model.kind})")
    n_steps = _evaluation_step(t_eval, dt, n_steps)
    if not 0.0 < window_fraction <= 1.0:
        raise ValueError(f"window_fraction = {window_fraction}: must lie in (0, 1]")
    integrator = make_solver() if integrator is None else integrator
    dt = jnp.asarray(dt, model.ell.dtype)
    space = parameter_space(model, components)
    _, ref = simulate(aligned(model), integrator, n_steps=n_steps, dt=dt)
    return Study(model=model, integrator=integrator, dt=dt, ref_u=ref.tracer_u, ref_v=ref.tracer_v,
                 base=model.chi_static, space=space, metric=metric, n_steps=n_steps,
                 window=max(1, int(round(window_fraction * n_steps))))


def _evaluation_step(t_eval, dt, n_steps) -> int:
    """The run length of a study: ``t_eval / dt`` rounded, else ``n_steps``; at least two steps."""
    dt = float(dt)
    if t_eval is None:
        if n_steps is None:
            raise ValueError("t_eval or n_steps: give the evaluation time (or step)")
        if int(n_steps) < 2:
            raise ValueError(f"n_steps = {n_steps}: must be at least two steps")
        return int(n_steps)
    steps = int(round(float(t_eval) / dt)) if np.isfinite(t_eval) else 0
    if steps < 2:
        raise ValueError(f"t_eval = {t_eval}: must be at least two steps (dt = {dt} s)")
    return steps


def tracer_deviation(study: Study, theta):
    """``(d_u, d_v)`` (n_steps, n_tr) in µm: tracer displacements at ``theta`` minus the aligned
    run's (``d_v`` is ``None`` in 1D)."""
    _, tr = simulate(study.configured(theta), study.integrator, n_steps=study.n_steps, dt=study.dt)
    du = (tr.tracer_u - study.ref_u) * M_TO_UM
    dv = None if tr.tracer_v is None else (tr.tracer_v - study.ref_v) * M_TO_UM
    return du, dv


def response_from_deviation(study: Study, du, dv):
    """The metric's response vector ``r`` (see the module table) from the deviations."""
    name, k = study.metric, study.n_steps - 1
    if name == "longitudinal_rms":
        return du[k]
    if name in ("lateral_rms", "lateral_max"):
        return dv[k]
    if name == "lateral_peak":
        return dv[k + 1 - study.window:k + 1].reshape(-1)
    t = (jnp.arange(study.n_steps) + 1.0) * study.dt  # walk_rate
    half = study.n_steps // 2
    t, y = t[half:], jnp.mean(dv[half:], axis=1)
    tc = t - jnp.mean(t)
    return (jnp.sum(tc * (y - jnp.mean(y))) / jnp.sum(tc**2))[None]


def aggregate(kind: str, r, smooth: bool = False, tau: float = SMOOTH_TAU_UM):
    """``max |r|`` (soft maximum with ``smooth``) or ``RMS(r)``; works on a trailing axis."""
    if kind == "rms":
        return jnp.sqrt(jnp.mean(r**2, axis=-1))
    if smooth:
        a = jnp.sqrt(r**2 + tau**2)
        return tau * jax.nn.logsumexp(a / tau, axis=-1)
    return jnp.max(jnp.abs(r), axis=-1)


def response(study: Study, theta):
    """``r(θ)`` of the study's metric (see the module table)."""
    return response_from_deviation(study, *tracer_deviation(study, theta))


def metric_value(study: Study, theta, smooth: bool = False):
    """The study's metric at ``theta`` (P,) in µm (µm/s for ``walk_rate``)."""
    return aggregate(study.aggregate, response(study, theta), smooth and study.metric == "lateral_peak")


def evaluate(study: Study, theta):
    """Everything a sweep stores for one configuration: ``metric`` () and the tracer deviations
    at ``t_eval``, ``longitudinal_um`` and (2D) ``lateral_um`` (n_tr,)."""
    du, dv = tracer_deviation(study, theta)
    out = {"metric": aggregate(study.aggregate, response_from_deviation(study, du, dv)),
           "longitudinal_um": du[-1]}
    if dv is not None:
        out["lateral_um"] = dv[-1]
    return out
