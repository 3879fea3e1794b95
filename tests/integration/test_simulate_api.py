"""The contract of the run entry point :func:`jaxbelt.simulate`.

One compiled program per model structure, solver, step count and records: another time step or
another misalignment runs it again (compilations counted with ``jax.monitoring``, never timed);
``dt`` is a traced, differentiable value; every solver of the registry runs through
:func:`jaxbelt.make_solver` and agrees with the dense reference; a scene's own settings come in
one :class:`jaxbelt.RunOptions`; bad input fails with a clear message before anything compiles;
importing the package changes no process-wide setting; a run with a progress bar is the same run.
"""

import dataclasses
import os
import subprocess
import sys
import tomllib

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from helpers import COARSE_2D_TWO_ROLLER, COMPILE_EVENT, TRACE_EVENT, counting_compiles, load, scene_with
from jaxbelt.integrators import solver_name
from jaxbelt.registry import INTEGRATORS, LINEAR_SOLVERS
from jaxbelt.run_checks import check_start_masses

# the idle roller of the two-roller machine misaligned; 30 steps: whole checkpoint chunks, the run
# length other modules compile for the 1D scenes
SCENE_1D, N_1D = "two-roller-1d-train1", 30
# the coarse 2D belt on the two-roller machine, 5 steps of 20 ms
SCENE_2D = COARSE_2D_TWO_ROLLER + "[time]\ndt_s = 0.02\nt_end_s = 0.1\n"


@pytest.fixture(scope="module")
def one_d():
    return load(SCENE_1D, n_steps=N_1D)


@pytest.fixture(scope="module")
def two_d():
    return load(jb.scene_from_dict(tomllib.loads(SCENE_2D)))


def test_the_compile_counter_sees_a_compile():
    with counting_compiles() as events:
        jax.jit(lambda x: jnp.sin(x) * 2.25 + 0.125)(jnp.arange(7.0)).block_until_ready()
    assert events.count(COMPILE_EVENT) >= 1 and events.count(TRACE_EVENT) >= 1


def test_compile_simulate_compiles_what_simulate_then_runs(one_d):
    """compile_simulate compiles (or loads) the run without running it; simulate with the same
    settings then traces and compiles nothing."""
    model, opts = one_d
    opts = opts.replace(n_steps=opts.n_steps + 7)  # a run length no other test compiles
    with counting_compiles() as warm:
        jb.timeloop.compile_simulate(model, opts.solver, n_steps=opts.n_steps, dt=opts.dt, saveat=opts.saveat)
    assert COMPILE_EVENT in warm and TRACE_EVENT in warm
    with counting_compiles() as events:
        jb.simulate(model, **opts)
    assert events == []


def _misaligned(case, model):
    if case == "1d":
        return jb.with_misalignment(model, translation=jnp.array([0.0, 1e-3]))
    return jb.with_misalignment(model, translation=jnp.zeros((2, 3)).at[1, 2].set(5e-4),
                                rotation=jnp.zeros((2, 3)).at[1, 0].set(2e-4))


@pytest.mark.parametrize("case", ["1d", "2d"])
def test_another_dt_or_misalignment_does_not_compile_again(case, one_d, two_d):
    """The first call compiles (or loads) the run; the second with another ``dt``, the third with
    another misalignment and the fourth with both trace and compile nothing, and each is a run of
    its own (its records differ)."""
    model, opts = one_d if case == "1d" else two_d
    moved = _misaligned(case, model)  # built before counting: its eager updates are not the run's
    first = jb.simulate(model, **opts)[1]
    with counting_compiles() as events:
        runs = [jb.simulate(model, **opts.replace(dt=0.8 * opts.dt))[1], jb.simulate(moved, **opts)[1],
                jb.simulate(moved, **opts.replace(dt=0.9 * opts.dt))[1]]
    assert events == []
    np.testing.assert_allclose(np.asarray(runs[0].t), 0.8 * np.asarray(first.t), rtol=1e-14)
    for tr in runs:
        assert float(jnp.max(jnp.abs(tr.tracer_u - first.tracer_u))) > 1e-9  # m
    assert float(jnp.max(jnp.abs(runs[2].tracer_u - runs[1].tracer_u))) > 1e-9


def test_dt_traced_under_jit_equals_the_eager_run_and_has_a_gradient(one_d):
    """``dt`` as a traced value inside ``jax.jit`` gives the eager call's trajectory, and reverse
    mode w.r.t. ``dt`` matches central differences."""
    model, opts = one_d

    def metric(dt):
        tr = jb.simulate(model, **opts.replace(dt=dt))[1]
        return jnp.sum(tr.tracer_u[-1] ** 2) * 1e6 + jnp.mean(tr.tracer_u) * 1e3 + jnp.mean(tr.roller_velocity), tr

    dt0 = opts.dt
    (value, traced), g = jax.jit(jax.value_and_grad(metric, has_aux=True))(dt0)
    eager = jb.simulate(model, **opts)[1]
    for a, b in zip(jax.tree.leaves(traced), jax.tree.leaves(eager)):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-12, atol=1e-12 * float(jnp.max(jnp.abs(b))))
    assert float(value) == pytest.approx(float(metric(dt0)[0]), rel=1e-12)
    h = 1e-5 * dt0
    fd = (float(metric(dt0 + h)[0]) - float(metric(dt0 - h)[0])) / (2 * h)
    assert np.isfinite(float(g)) and abs(fd) > 0
    assert float(g) == pytest.approx(fd, rel=1e-5)


_SOLVERS = [("direct", name) for name in LINEAR_SOLVERS] + [(name, None) for name in INTEGRATORS if name != "direct"]


@pytest.fixture(scope="module")
def dense_run(one_d):
    model, opts = one_d
    return jb.simulate(model, **opts.replace(solver=jb.DirectBackwardEuler(jb.Dense())))


@pytest.mark.parametrize("integrator,linear_solver", _SOLVERS, ids=[f"{i}-{ls}" if ls else i for i, ls in _SOLVERS])
def test_every_registered_solver_runs_and_agrees_with_dense(one_d, dense_run, integrator, linear_solver):
    model, opts = one_d
    solver = jb.make_solver(integrator, linear_solver)
    assert solver_name(solver) == (f"direct/{linear_solver}" if linear_solver else integrator)
    s, tr = jb.simulate(model, **opts.replace(solver=solver))
    s_ref, tr_ref = dense_run
    scale = float(jnp.max(jnp.abs(s_ref.u)))
    assert float(jnp.max(jnp.abs(s.u - s_ref.u))) < 1e-11 * scale
    assert float(jnp.max(jnp.abs(tr.tracer_u - tr_ref.tracer_u))) < 1e-11 * scale
    np.testing.assert_allclose(np.asarray(tr.roller_velocity), np.asarray(tr_ref.roller_velocity), rtol=1e-10, atol=1e-10)


def test_run_options_from_scene():
    """:meth:`jaxbelt.RunOptions.from_scene` reads ``[time]``, ``[output]`` and ``[solver]`` (the
    adjoint's checkpointing is the default), and ``simulate(model, **options)`` runs with them."""
    def mutate(d):
        d["time"] = {"dt_s": 0.004, "t_end_s": 0.1}
        d["output"] = {"every": 5, "fields": "full"}
        d["solver"] = {"integrator": "direct", "linear_solver": "cyclic-reduction", "transport": "source"}

    scene = scene_with(mutate)
    opts = jb.RunOptions.from_scene(scene)
    assert opts.dt == 0.004 and opts.n_steps == 25 and opts.t_end == pytest.approx(0.1, rel=1e-14)
    assert opts.saveat == jb.SaveAt(every=5, fields=True)
    assert solver_name(opts.solver) == "direct/cyclic-reduction" and opts.solver.transport == "source"
    assert dict(opts) == {"solver": opts.solver, "n_steps": 25, "dt": 0.004, "saveat": opts.saveat,
                          "adjoint": jb.Checkpointed()}
    assert opts.replace(n_steps=7).n_steps == 7 and opts.n_steps == 25
    default = jb.RunOptions.from_scene(jb.load_scene("two-roller-1d"))
    assert solver_name(default.solver) == "direct/kept-interior" and default.solver.transport == "shift"
    assert default.saveat == jb.SaveAt() and (default.dt, default.n_steps) == (0.005, 1000)

    model = jb.build_model(scene)
    state, tr = jb.simulate(model, **opts)
    np.testing.assert_allclose(np.asarray(tr.t), 0.004 * np.arange(5, 26, 5), rtol=1e-14)
    assert tr.u.shape == (5, model.n_xi, 1) and int(state.step) == 25
    np.testing.assert_array_equal(np.asarray(tr.u[-1]), np.asarray(state.u))


@pytest.mark.parametrize("dt,message", [(0.0, r"dt = 0\.0: must be a positive number"),
                                        (-0.001, r"dt = -0\.001: must be a positive number"),
                                        (float("nan"), r"dt = nan: must be a positive number"),
                                        (0.01, r"dt = 0\.01 s violates the CFL condition.*use dt <= 0\.007069 s \(the bound is 0\.007854 s")])
def test_bad_time_step_is_refused_before_compiling(one_d, dt, message):
    model, opts = one_d
    with counting_compiles() as events, pytest.raises(ValueError, match=message):
        jb.simulate(model, **opts.replace(dt=dt))
    assert events == []


def test_bad_run_settings_are_refused(one_d):
    model, opts = one_d
    with pytest.raises(ValueError, match=r"n_steps = -1: must be at least 0"):
        jb.simulate(model, **opts.replace(n_steps=-1))
    with pytest.raises(ValueError, match=r"SaveAt\(every=0\): must be at least 1"):
        jb.SaveAt(every=0)
    with pytest.raises(ValueError, match=r"unknown integrator 'implicit' \(one of direct, naive, eliminated\)"):
        jb.make_solver("implicit")
    with pytest.raises(ValueError, match=r"unknown linear solver 'lu' \(one of kept-interior, .*dense\)"):
        jb.make_solver("direct", "lu")


def test_import_changes_no_process_setting():
    """``import jaxbelt`` in a fresh interpreter leaves JAX in float32 and the BLAS threads alone;
    :func:`jaxbelt.enable_x64` switches float64 on."""
    code = ("import os, jax, jaxbelt\n"
            "print(jax.config.jax_enable_x64, os.environ.get('OPENBLAS_NUM_THREADS'))\n"
            "jaxbelt.enable_x64()\n"
            "print(jax.config.jax_enable_x64, jax.numpy.zeros(1).dtype)\n")
    env = {k: v for k, v in os.environ.items() if k not in ("JAX_ENABLE_X64", "OPENBLAS_NUM_THREADS")}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True)
    assert out.stdout.split("\n")[:2] == ["False None", "True float64"]


@pytest.fixture(scope="module")
def translated():
    """The idle roller 1 mm out: stable under both transport rules (on two-roller-1d-train1 the
    source rule extrapolates, :mod:`jaxbelt.transport`)."""
    return load("two-roller-1d-idle-translated", n_steps=205, saveat=jb.SaveAt(every=5))


@pytest.mark.parametrize("solver", [jb.make_solver(), jb.make_solver("direct", jb.Reuse(refine=0), transport="source")],
                         ids=["kept-interior", "reuse"])
def test_progress_bar_run_equals_one_call(translated, solver):
    """``progress=True`` runs compiled chunks of 200 steps (here 200 + 5) and gives the one-call
    result. With the source transport the step matrix drifts and the frozen factors of
    :class:`jaxbelt.Reuse` (no refinement) differ from the current matrix's: the chunks use the
    run's one factorisation (a run restarted from the 200th step, factored there, differs; it runs
    the same compiled chunks)."""
    model, opts = translated
    run = opts.replace(solver=solver)
    s1, tr1 = jb.simulate(model, **run)
    s2, tr2 = jb.simulate(model, **run, progress=True)
    assert tr2.t.shape == (41,)
    for a, b in zip(jax.tree.leaves((s1, tr1)), jax.tree.leaves((s2, tr2))):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-13, atol=1e-13 * float(jnp.max(jnp.abs(b))))
    if isinstance(solver.linear_solver, jb.Reuse):  # the test can fail
        s200 = jb.simulate(model, **run.replace(n_steps=200), progress=True)[0]
        restarted = jb.simulate(model, **run.replace(n_steps=5), y0=s200, progress=True)
        scale = float(jnp.max(jnp.abs(s1.u)))
        assert float(jnp.max(jnp.abs(restarted[0].u - s1.u))) > 1e-10 * scale


def test_solver_objects_reject_bad_settings_when_built():
    with pytest.raises(ValueError, match="transport = 'nope'"):
        jb.make_solver(transport="nope")
    with pytest.raises(ValueError, match="unknown rule"):
        jb.NaiveBackwardEuler(transport="upwind")
    with pytest.raises(TypeError, match="a linear solver object"):
        jb.DirectBackwardEuler("dense")


def test_a_start_state_with_other_masses_is_refused_by_the_kept_interior_solver_only():
    """The kept-interior solver keeps its factors at the model's element masses; a start state with
    other masses would be stepped with the wrong matrix. A solver that factors every step takes it,
    and round-off in the masses (a state carried from another run) is no reason to refuse."""
    model, opts = load(SCENE_1D)
    y0 = jb.initial_state(model)
    moved = dataclasses.replace(y0, m_e=y0.m_e * 1.01)
    kept = jb.DirectBackwardEuler(jb.KeptInterior())
    with pytest.raises(ValueError, match=r"element masses differ .*Structured"):
        jb.simulate(model, kept, n_steps=1, dt=opts.dt, y0=moved)
    check_start_masses(model, jb.DirectBackwardEuler(jb.Structured()), moved)  # factors every step: taken
    check_start_masses(model, kept, dataclasses.replace(y0, m_e=y0.m_e * (1.0 + 1e-12)))
