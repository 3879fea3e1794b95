"""A tolerance study (:class:`Study`): one question on one model — the metric
(:mod:`jaxbelt.design.metrics`), its evaluation time or steady operation, the varied components,
the aligned reference — and the runs that answer it at a design vector (:func:`run_deviation`,
:func:`response`, :func:`metric_value`, :func:`evaluate`). Built by :func:`make_study` (one model),
:func:`make_study_at` (a model and its batch of configurations at once) or :func:`study_on` (the
same question on another grid of the scene). The linear response of the runs at ``θ = 0`` is a
:class:`~jaxbelt.design.linearisation.LinearDeviation` beside the study (:func:`make_study` with ``jacobian=True``,
:func:`linearise`), passed to what reads it."""

from __future__ import annotations


import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..infra.programs import stored_jit
from ..misalignment import TO_SI, ParameterSpace, aligned, apply, dof_directions, parameter_space
from ..model import BeltModel
from ..state import BeltState, prolongate
from ..steady import (NoSteadyStateError, actuator_jitter, check_steady, forward_jacobian, linear_start,
                      period_steps, steady_states, steady_state, steady_with_tangents, walks)
from ..run_checks import check_finite
from ..timeloop import RunOptions, simulate
from .linearisation import LinearDeviation, linear_deviation
from .metrics import (CLOSED_LOOP_WINDOW, METRICS, M_TO_UM, OPEN_LOOP_WINDOW, RAD_TO_MRAD, limit_values_from_deviation,
                      metric_from_deviation, response_from_deviation, saturation)


class Study(eqx.Module):
    """One tolerance question on one model: the metric, its evaluation time, the varied
    components and the aligned reference run. Build with :func:`make_study`.

    **Fields:** ``model``; ``options`` the run settings of every run (:class:`jaxbelt.RunOptions`:
    its ``solver``; its ``dt`` the time step, s, held as an array, so studies at other time steps
    share compiled programs; its ``n_steps`` the run length, the evaluation step; its ``adjoint``
    the checkpointing of gradients through the runs; every step recorded, :func:`study_options`);
    ``ref_u``, ``ref_v``
    (n_steps, n_tr) tracer displacements of the aligned run, m, every step recorded (``ref_v``
    ``None`` in 1D); ``base`` (q,) the scene's own misalignment around which ``theta`` is
    measured; ``space`` the varied components; ``metric``; ``window`` the steps of the evaluation window (``lateral_peak``, and every
    windowed metric of a steered machine); ``limit_names`` the metrics of a study with several
    limits at once (module docstring), else ``()``, and ``limit_values`` (n_limits,) their limits
    (an array: studies that differ in the limits only share compiled programs); ``ref_angle``
    (n_steps, n_c) the aligned run's steering actuator angles, mrad (``None`` without a loop);
    ``steady`` whether the study judges steady operation (module
    docstring, *Steady operation*): then ``options.n_steps = window = 1`` and every history above has one
    row, the steady state's; ``period_steps`` the steady map's period in steps; ``jitter_mrad``
    (n_c,) the aligned machine's actuator jitter around its steady angle from sensor noise and
    edge profile, mrad (steady studies of a steered machine, else ``None``); ``steady_start``
    the aligned machine's steady state; ``steady_tangents`` its derivatives with respect to ``θ``
    (:func:`jaxbelt.steady.state_fields`, trailing axis P; a steady study made with
    ``jacobian=True``): every steady solve of the study starts at the linear prediction
    :func:`jaxbelt.steady.linear_start`, or without them at the aligned steady state. Both are
    where the study's runs start, so they belong to the study; the linear response of the
    deviations, which no run reads, is a :class:`~jaxbelt.design.linearisation.LinearDeviation` beside it.
    Set from those: ``aggregate`` how the response is aggregated (``"max"`` with several limits,
    else the metric's), ``steered`` whether the machine has steering loops (then its metrics
    read the window in closed loop) and ``unit`` the unit of the metric values (µm, mrad or µm/s:
    the first limit's with several limits, whose measure is on that limit's scale).
    """

    model: BeltModel
    options: RunOptions
    ref_u: jax.Array
    ref_v: jax.Array | None
    base: jax.Array
    space: ParameterSpace = eqx.field(static=True)
    metric: str = eqx.field(static=True)
    window: int = eqx.field(static=True)
    limit_names: tuple = eqx.field(static=True, default=())
    limit_values: jax.Array | None = None
    ref_angle: jax.Array | None = None
    steady: bool = eqx.field(static=True, default=False)
    period_steps: int = eqx.field(static=True, default=1)
    jitter_mrad: jax.Array | None = None
    steady_start: BeltState | None = None
    steady_tangents: tuple | None = None
    aggregate: str = eqx.field(static=True, init=False)
    steered: bool = eqx.field(static=True, init=False)
    unit: str = eqx.field(static=True, init=False)

    def __post_init__(self):
        # read by every evaluation: plain attributes, set once from the fields they follow
        self.aggregate = "max" if self.limit_names else METRICS[self.metric].aggregate
        self.steered = self.model.control is not None  # steering loops: metrics read the window closed-loop
        # the unit of the metric values: the first limit's with several (on_limit_scale), else the metric's
        self.unit = METRICS[self.limit_names[0] if self.limit_names else self.metric].unit

    @property
    def limits(self) -> tuple:
        """``((metric, limit), ...)`` of a study with several limits, else ``()``."""
        if not self.limit_names:
            return ()
        return tuple(zip(self.limit_names, (float(v) for v in np.asarray(self.limit_values))))

    @property
    def t_eval(self) -> float | None:
        """The evaluation time ``n_steps × dt``, s (concrete studies only); ``None`` for steady
        operation."""
        return None if self.steady else self.options.n_steps * float(self.options.dt)

    @property
    def t_window(self) -> tuple[float, float] | None:
        """The evaluation window ``(start, end)``, s: the last ``window`` steps of the run;
        ``None`` for steady operation."""
        return None if self.steady else ((self.options.n_steps - self.window) * float(self.options.dt), self.t_eval)

    @property
    def range_mrad(self) -> float | None:
        """The steering actuators' range limit, mrad (the smallest over the loops); ``None``
        without a loop."""
        return None if self.model.control is None else float(jnp.min(self.model.control.limit)) * RAD_TO_MRAD

    def configured(self, theta) -> BeltModel:
        """The model at design vector ``theta`` (P,), mm / mrad around the scene's misalignment."""
        return apply(self.model, self.space, theta, self.base)


def _mrad(angle):
    """Actuator angles in rad (``None`` without a loop) in mrad."""
    return None if angle is None else angle * RAD_TO_MRAD


def _check_metric(model: BeltModel, metric: str):
    if metric not in METRICS:
        raise ValueError(f"metric = {metric!r}: unknown (one of {', '.join(METRICS)})")
    if METRICS[metric].needs_2d and model.kind != "2d":
        raise ValueError(f"metric = {metric!r}: a lateral metric needs a 2D scene (this one is {model.kind})")
    if METRICS[metric].needs_loop and model.control is None:
        raise ValueError(f"metric = {metric!r}: needs a steering loop ([[control]]); this machine has none")


def make_study(model: BeltModel, metric: str, options: RunOptions, *, t_eval: float | None = None, components=None,
               window_fraction: float | None = None, jacobian: bool = False,
               steady: bool = False) -> Study | tuple[Study, LinearDeviation]:
    """Set up a study: validate the metric and time, select the components, run the aligned
    reference once. **Returns:** the :class:`Study`; with ``jacobian``, ``(study, linear)``.

    With ``jacobian``, also the run's derivatives with respect to every component at the scene's
    own misalignment (``linear``, a :class:`~jaxbelt.design.linearisation.LinearDeviation`), for the linear response at
    ``θ = 0``. On an aligned scene that run is the reference itself: one forward-mode program
    gives both (the reference is the primal the tangents ride on), where a study and then its
    Jacobian (:func:`linearise`) would run the reference twice and compile two programs. The study
    is the same with and without ``jacobian`` (but for a steady study's ``steady_tangents``, the
    start of its steady solves), and so are the programs that run it.

    **Arguments:** ``metric`` (one of :data:`~jaxbelt.design.metrics.METRICS`); ``options`` the
    run settings (:class:`jaxbelt.RunOptions`, e.g. a scene's ``RunOptions.from_scene(scene)``:
    its ``solver`` runs every configuration, its ``dt`` is the time step, its ``n_steps`` the
    evaluation step when ``t_eval`` is not given); ``t_eval`` evaluation time in s, rounded to
    whole steps of ``dt``; ``components`` as in :func:`jaxbelt.misalignment.parameter_space`;
    ``window_fraction`` of ``[0, t_eval]``, the evaluation window (default 0.1,
    ``lateral_peak``'s; 0.2 on a steered machine, where every windowed metric reads it);
    ``steady`` judge steady operation instead of a time-stepped window (module docstring of
    :mod:`jaxbelt.design.metrics`; ``t_eval``, ``n_steps`` and ``window_fraction`` are then not
    read).
    """
    if steady:
        return _make_steady_study(model, metric, options, components, jacobian)
    frame = _study_frame(model, metric, t_eval, options, components, window_fraction)
    if jacobian and not np.any(np.asarray(frame["base"])):
        ref, (du, dv, dangle) = _reference_and_tangents(model, frame["space"], frame["options"])
        check_finite(ref, frame["options"].dt)  # a diverging reference is named, as simulate names it
        u, v, angle = ref.tracer_u, ref.tracer_v, ref.control_u
        zero = lambda a: None if a is None else jnp.zeros_like(a)  # noqa: E731
        study = Study(**frame, ref_u=u, ref_v=v, ref_angle=_mrad(angle))
        return study, linear_deviation((zero(u), zero(v), study.ref_angle),
                                        (du * M_TO_UM, None if dv is None else dv * M_TO_UM, _mrad(dangle)))
    _, ref = simulate(aligned(model), **frame["options"])
    study = Study(**frame, ref_u=ref.tracer_u, ref_v=ref.tracer_v,
                  ref_angle=_mrad(ref.control_u))
    return (study, linearise(study)) if jacobian else study


def _steady_rows(s):
    """A steady state's tracers and angles as one-row histories ``(u, v, angle)`` (m, m, rad)."""
    row = lambda a: None if a is None else a[None]  # noqa: E731
    return row(s.tracer_u), row(s.tracer_v), row(s.angle)


DESIGN_TANGENT_RTOL = 1e-6  # GMRES's relative residual of a steady study's tangents (a linear model
# that nonlinear solves verify: its columns are then right to 1e-4 of their size, against 1e-8's)


def _steady_frame(model, metric, options, components) -> dict:
    _check_metric(model, metric)
    options = study_options(model, options, 1)
    return dict(model=model, options=options, base=model.chi_static, space=parameter_space(model, components),
                metric=metric, window=1, steady=True, period_steps=period_steps(model, options.dt))


def _make_steady_study(model, metric, options, components, jacobian):
    """:func:`make_study` of steady operation (module docstring)."""
    frame = _steady_frame(model, metric, options, components)
    if walks(model):
        raise ValueError("steady operation: this machine walks (lateral transport without a steering loop); "
                         "judge a time-stepped window instead (t_eval)")
    base_is_zero = not np.any(np.asarray(frame["base"]))
    tangents = None
    if jacobian and base_is_zero:
        # derivatives along the varied components (θ in design units), in the program every steady
        # solve of this model's shapes runs (jaxbelt.steady.steady_with_tangents)
        q, P = model.chi_static.shape[0], frame["space"].size
        directions = dof_directions(model, frame["space"].chi_index, TO_SI, rows=q)
        s, J = steady_with_tangents(model, frame["options"].solver, dt=frame["options"].dt, directions=directions,
                                    n_tangents=P,
                                    period_steps=frame["period_steps"], tangent_rtol=DESIGN_TANGENT_RTOL)
        (du, dv, dangle), tangents = jax.tree.map(lambda a: a[..., :P], (J[:3], J[3]))
    else:  # the same compiled program, asked for no tangents (the verification solves' program)
        s = steady_with_tangents(aligned(model), frame["options"].solver, dt=frame["options"].dt, n_tangents=0,
                                 period_steps=frame["period_steps"])[0]
    check_steady(s, model)
    jitter = (None if model.control is None else
              actuator_jitter(aligned(model), frame["options"].solver, frame["options"].dt, s))
    u, v, angle = _steady_rows(s)
    study = Study(**frame, ref_u=u, ref_v=v, ref_angle=_mrad(angle), jitter_mrad=jitter,
                  steady_start=s.state, steady_tangents=tangents)
    if not jacobian:
        return study
    if not base_is_zero:
        return study, linearise(study)
    row = lambda a, k: None if a is None else a[None] * k  # noqa: E731
    zero = lambda a: None if a is None else jnp.zeros_like(a)  # noqa: E731
    return study, linear_deviation((zero(u), zero(v), _mrad(angle)),
                                    (row(du, M_TO_UM), row(dv, M_TO_UM), row(dangle, RAD_TO_MRAD)))


@stored_jit
def _reference_and_tangents(model, space, options):
    """The run of ``model`` (aligned; its :class:`~jaxbelt.timeloop.Trajectory`) and the
    derivatives of its tracer histories and actuator angles with respect to ``θ`` at ``θ = 0``,
    each with a trailing axis P: one forward-mode pass, the run itself its primal."""

    def run(theta):
        _, tr = simulate(apply(model, space, theta), **options)
        return (tr.tracer_u, tr.tracer_v, tr.control_u), tr

    J, ref = jax.jacfwd(run, has_aux=True)(jnp.zeros(space.size, model.chi_static.dtype))
    return ref, J


@stored_jit
def _deviation_tangents(study: Study):
    """:func:`run_deviation` at ``θ = 0`` and its derivatives: ``(primal, tangents)``."""
    fn, theta = (lambda t: (run_deviation(study, t),) * 2), jnp.zeros(study.space.size, study.base.dtype)
    J, primal = forward_jacobian(fn, theta, has_aux=True) if study.steady else jax.jacfwd(fn, has_aux=True)(theta)
    return primal, J


def linearise(study: Study) -> LinearDeviation:
    """The study's deviations at ``θ = 0`` and their derivatives (:class:`~jaxbelt.design.linearisation.LinearDeviation`), from
    one forward-mode run (implicit tangents of the steady state in steady operation)."""
    return linear_deviation(*_deviation_tangents(study))


def _study_frame(model, metric, t_eval, options, components, window_fraction) -> dict:
    """A study's fields but the aligned reference, validated (:func:`make_study`)."""
    _check_metric(model, metric)
    n_steps = _evaluation_step(t_eval, options.dt, options.n_steps)
    if window_fraction is None:
        window_fraction = OPEN_LOOP_WINDOW if model.control is None else CLOSED_LOOP_WINDOW
    if not 0.0 < window_fraction <= 1.0:
        raise ValueError(f"window_fraction = {window_fraction}: must lie in (0, 1]")
    return dict(model=model, options=study_options(model, options, n_steps), base=model.chi_static,
                space=parameter_space(model, components), metric=metric,
                window=max(1, int(round(window_fraction * n_steps))))


def study_options(model: BeltModel, options: RunOptions, n_steps: int) -> RunOptions:
    """The run settings of a study's runs from the caller's ``options``: its solver, time step
    (held as an array of the model's dtype: traced, so studies at other time steps share
    programs) and adjoint, ``n_steps`` steps, every step recorded (a study reads whole histories)."""
    return RunOptions(options.solver, int(n_steps), jnp.asarray(options.dt, model.ell.dtype), adjoint=options.adjoint)


@stored_jit
def _aligned_and_configured(model, space, options, thetas):
    """The tracer histories (m + 1, n_steps, n_tr) and actuator angles of the aligned machine and
    of ``model`` at each row of ``thetas`` (m, P), as one ``vmap`` batch."""
    chis = jnp.concatenate([jnp.zeros_like(model.chi_static)[None],
                            jax.vmap(lambda t: apply(model, space, t).chi_static)(thetas)])

    def one(chi):
        _, tr = simulate(model.replace(chi_static=chi), **options)
        return tr.tracer_u, tr.tracer_v, tr.control_u

    return jax.vmap(one)(chis)


def make_study_at(model: BeltModel, metric: str, thetas, options: RunOptions, *, t_eval: float | None = None,
                  components=None, window_fraction: float | None = None, limits=(), steady: bool = False,
                  jitter_mrad=None, starts=None):
    """:func:`make_study` and the study's values at ``thetas`` (m, P) from one ``vmap`` batch of
    m + 1 runs, the aligned reference among them. On a CPU a batch of m + 1 costs far less than
    a reference run and then a batch of m: one run's sequential sweeps leave the cores idle.

    **Arguments:** as :func:`make_study`; ``limits`` ``((metric, limit), ...)`` as
    :func:`with_limits` (then the study is the one with the limits). **Returns:** ``(study,
    values)``: ``values`` (m,) the metric, or with ``limits`` (m, n_limits) each limit's value in
    its own unit (:func:`limit_values`). With ``steady``, the study of steady operation, its m + 1
    steady solves one batch (:func:`jaxbelt.steady.steady_states`), each from its row of
    ``starts`` (the aligned machine first; a :class:`~jaxbelt.BeltState` with a leading axis m + 1,
    e.g. another grid's steady states carried over by :func:`study_on`; default the static
    equilibrium); ``jitter_mrad`` its actuator jitter (default: measured here)."""
    if steady:
        frame = _steady_frame(model, metric, options, components)
        thetas = jnp.asarray(thetas, model.chi_static.dtype).reshape(-1, frame["space"].size)
        chis = jnp.concatenate([jnp.zeros_like(model.chi_static)[None],
                                jax.vmap(lambda t: apply(model, frame["space"], t).chi_static)(thetas)])
        first = steady_states(model, frame["options"].solver, dt=frame["options"].dt, chis=chis, y0s=starts,
                              period_steps=frame["period_steps"])
        (u, v, angle), converged = jax.vmap(_steady_rows)(first), first.converged
        if not np.all(np.asarray(converged)):
            raise NoSteadyStateError(f"no steady operation at {int(np.sum(~np.asarray(converged)))} of "
                                     f"{len(chis)} configurations: the fixed-point iteration did not converge")
        aligned_steady = jax.tree.map(lambda a: a[0], first)
        if model.control is not None and jitter_mrad is None:
            jitter_mrad = actuator_jitter(aligned(model), frame["options"].solver, frame["options"].dt, aligned_steady)
        frame.update(jitter_mrad=jitter_mrad, steady_start=aligned_steady.state)
    else:
        frame = _study_frame(model, metric, t_eval, options, components, window_fraction)
        thetas = jnp.asarray(thetas, model.chi_static.dtype).reshape(-1, frame["space"].size)
        u, v, angle = _aligned_and_configured(model, frame["space"], frame["options"], thetas)
    angle = _mrad(angle)
    study = Study(**frame, ref_u=u[0], ref_v=None if v is None else v[0], ref_angle=None if angle is None else angle[0])
    if limits:
        study = with_limits(study, limits)

    def values(uk, vk, ak):
        du, dv, _ = deviation(study, uk, vk, None)
        if study.limit_names:
            return limit_values_from_deviation(study, du, dv, ak)
        return metric_from_deviation(study, du, dv, ak)

    rest = lambda a: None if a is None else a[1:]  # noqa: E731
    return study, np.asarray(jax.vmap(values)(u[1:], rest(v), rest(angle)), dtype=float)


def study_on(model: BeltModel, study: Study, thetas, options: RunOptions, *, limits=()):
    """:func:`make_study_at` of ``study``'s question — its metric, components, evaluation time and
    window — on ``model`` (the same scene on another grid, run with ``options``): ``(study,
    values)`` at ``thetas`` (m, P), the aligned reference in the same batch."""
    if study.steady:
        return make_study_at(model, study.metric, thetas, options, components=list(study.space.labels()),
                             limits=limits, steady=True, jitter_mrad=study.jitter_mrad,
                             starts=_carried_starts(study, model, thetas))
    return make_study_at(model, study.metric, thetas, options, t_eval=study.t_eval, components=list(study.space.labels()),
                         window_fraction=study.window / study.options.n_steps, limits=limits)


def _carried_starts(study: Study, model: BeltModel, thetas):
    """Starts on ``model``'s grid for :func:`study_on`'s steady solves: the study's aligned steady
    state and, per configuration, its linear prediction there (:func:`jaxbelt.steady.linear_start`),
    carried over (:func:`jaxbelt.state.prolongate`); ``None`` without a steady state to carry."""
    if study.steady_start is None or model.kind != study.model.kind:
        return None
    thetas = np.asarray(thetas, float).reshape(-1, study.space.size)
    rows = [study.steady_start] + [study.steady_start if study.steady_tangents is None else
                                   linear_start(study.steady_start, study.steady_tangents,
                                                jnp.asarray(t, study.base.dtype)) for t in thetas]
    carried = [prolongate(s, study.model, model) for s in rows]
    return jax.tree.map(lambda *a: jnp.stack(a), *carried)


def with_limits(study: Study, limits) -> Study:
    """The study with several limits at once: ``limits`` ``{metric: limit}`` (or pairs), max-type
    metrics only, limits in each metric's unit (:func:`metric_unit`). Its response is every
    metric's response over its limit, stacked, times the first limit; its metric the largest ratio
    times the first limit (module docstring).
    An empty ``limits`` gives back the single-metric study (``limit_names = ()``)."""
    pairs = tuple((str(k), float(v)) for k, v in (limits.items() if isinstance(limits, dict) else limits))
    for name, limit in pairs:
        _check_metric(study.model, name)
        if METRICS[name].aggregate != "max":
            raise ValueError(f"limits: {name!r} is an RMS metric; several limits at once take max-type metrics "
                             f"({', '.join(k for k, v in METRICS.items() if v.aggregate == 'max')})")
        if not (np.isfinite(limit) and limit > 0):
            raise ValueError(f"limits: {name} = {limit}: must be a positive number")
    if len({n for n, _ in pairs}) != len(pairs):
        raise ValueError(f"limits: {[n for n, _ in pairs]} names a metric twice")
    return Study(model=study.model, options=study.options, ref_u=study.ref_u, ref_v=study.ref_v,
                 base=study.base, space=study.space, metric=study.metric, window=study.window,
                 limit_names=tuple(n for n, _ in pairs),
                 limit_values=jnp.asarray([v for _, v in pairs], study.base.dtype) if pairs else None,
                 ref_angle=study.ref_angle, steady=study.steady,
                 period_steps=study.period_steps, jitter_mrad=study.jitter_mrad, steady_start=study.steady_start,
                 steady_tangents=study.steady_tangents)


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


def run_deviation(study: Study, theta):
    """``(d_u, d_v, angle)``: the tracer displacements at ``theta`` minus the aligned run's,
    (n_steps, n_tr) µm (``d_v`` ``None`` in 1D), and the steering actuators' angles (n_steps,
    n_c), mrad (``None`` without a loop)."""
    if study.steady:
        s = steady_state(study.configured(theta), study.options.solver, dt=study.options.dt,
                         period_steps=study.period_steps,
                         y0=steady_start(study, theta))
        return steady_deviation(study, s)
    _, tr = simulate(study.configured(theta), **study.options)
    return deviation(study, tr.tracer_u, tr.tracer_v, tr.control_u)


def steady_start(study: Study, theta):
    """Where a steady study's solve at ``theta`` starts: the aligned steady state, moved along its
    derivatives where the study has them (:func:`jaxbelt.steady.linear_start`)."""
    if study.steady_tangents is None:
        return study.steady_start
    return linear_start(study.steady_start, study.steady_tangents, theta)


def steady_deviation(study: Study, s):
    """:func:`run_deviation` of a steady study from the steady state ``s`` at a configuration (its
    solve done elsewhere, e.g. :func:`jaxbelt.steady.steady_states`); an unconverged solve is
    NaN, never a number."""
    u, v, angle = _steady_rows(s)
    return deviation(study, u + jnp.where(s.converged, 0.0, jnp.nan), v, angle)


def deviation(study: Study, u, v, angle):
    """``(d_u, d_v, angle)`` of :func:`run_deviation` from a run's (or steady state's) tracer
    displacements ``u``, ``v`` (…, n_tr) m and actuator angles rad (``v``, ``angle`` may be
    ``None``): the deviations from the aligned reference in µm, the angles in mrad."""
    du = (u - study.ref_u) * M_TO_UM
    dv = None if v is None else (v - study.ref_v) * M_TO_UM
    return du, dv, _mrad(angle)


def tracer_deviation(study: Study, theta):
    """``(d_u, d_v)`` (n_steps, n_tr) in µm: tracer displacements at ``theta`` minus the aligned
    run's (``d_v`` is ``None`` in 1D)."""
    return run_deviation(study, theta)[:2]


def response(study: Study, theta):
    """``r(θ)`` of the study's metric (see the module table)."""
    return response_from_deviation(study, *run_deviation(study, theta))


def metric_value(study: Study, theta, smooth: bool = False):
    """The study's metric at ``theta`` (P,) in its unit (µm; µm/s for ``walk_rate``, mrad for
    ``steering_max``, the largest ratio times the first limit with several limits)."""
    return metric_from_deviation(study, *run_deviation(study, theta),
                                 smooth=smooth and METRICS[study.metric].soft_maximum and not study.limit_names)


def limit_values(study: Study, theta):
    """Every limited metric of a study with several limits (:func:`with_limits`) at ``theta``:
    (n_limits,), each in its own unit, in the order of ``study.limits``."""
    return limit_values_from_deviation(study, *run_deviation(study, theta))


def evaluate(study: Study, theta):
    """Everything a sweep stores for one configuration: ``metric`` () and the tracer deviations
    at ``t_eval``, ``longitudinal_um`` and (2D) ``lateral_um`` (n_tr,); on a steered machine also
    ``steering_mrad`` () the largest actuator angle in the window and ``saturated`` () whether
    the actuator reached its range limit there (:func:`saturation`)."""
    return evaluate_deviation(study, *run_deviation(study, theta))


def evaluate_deviation(study: Study, du, dv, angle):
    """:func:`evaluate` from a configuration's deviations (:func:`run_deviation`)."""
    out = {"metric": metric_from_deviation(study, du, dv, angle), "longitudinal_um": du[-1]}
    if dv is not None:
        out["lateral_um"] = dv[-1]
    if angle is not None:
        out["steering_mrad"], out["saturated"] = saturation(study, angle)
    return out
