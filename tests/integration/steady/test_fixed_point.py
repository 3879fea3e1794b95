"""The fixed point of the period map (:mod:`jaxbelt.steady.fixed_point`) against long time-stepped
runs, its implicit derivatives against central differences, and the machines without one."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.misalignment import apply, parameter_space
from jaxbelt.steady import period_steps, quiet, steady_state, steady_tangents, steady_walk, steady_with_tangents


def test_steady_state_is_where_a_long_run_settles(machine, steady):
    """The fixed point of the time stepper's own map: a 160 s run of the noise-free machine
    approaches it (closer at every record) and ends within 0.1 % of a 20 µm limit of it; the loop's
    slow integral mode is what is still settling."""
    model, opts = machine
    assert bool(steady.converged) and float(steady.residual) < 1e-4
    _, tr = jb.simulate(quiet(model), opts.solver, n_steps=8000, dt=opts.dt, saveat=jb.SaveAt(every=1000))
    dv = np.abs(np.asarray(tr.tracer_v - steady.tracer_v)).max(axis=1) * 1e6  # per record, µm
    du = np.abs(np.asarray(tr.tracer_u[-1] - steady.tracer_u)).max() * 1e6
    assert np.all(np.diff(dv[2:]) < 0), dv
    assert dv[-1] < 0.02 and du < 0.02, (dv, du)
    # the loop holds the sensor on its setpoint with a non-zero angle (the drive is skewed)
    assert abs(float(steady.sensor_v[0])) < 1e-10
    assert abs(float(steady.angle[0])) > 1e-5
    np.testing.assert_allclose(np.asarray(tr.control_u[-1]), np.asarray(steady.angle), rtol=1e-3)


def test_steady_state_gradient_matches_central_differences(machine, steady):
    """The implicit-function-theorem tangents of the steady tracers and angle with respect to a
    roller translation and tilt equal central differences of converged steady solves, reverse
    mode (one transposed solve) equals the forward tangents, and so do the tangent solves at the
    known steady state (:func:`jaxbelt.steady.steady_tangents`)."""
    model, opts = machine
    space = parameter_space(model, "idle:dz,drive:ay")
    n_p = period_steps(model, opts.dt)

    @jax.jit
    def outputs(theta):
        s = steady_state(apply(model, space, theta), opts.solver, dt=opts.dt, period_steps=n_p, tol=1e-9)
        return jnp.concatenate([s.tracer_u, s.tracer_v, s.angle]) * 1e6

    theta0 = jnp.zeros(space.size)
    J = np.asarray(jax.jacfwd(outputs)(theta0))
    # the same derivatives from tangent solves at the known steady state (no Newton iteration)
    at_solution = steady_tangents(lambda t: apply(model, space, t), theta0, steady, opts.solver, dt=opts.dt,
                                  outputs=lambda m, state, rate: jnp.concatenate(
                                      [*jb.timeloop.tracer_values(m, state.u), state.control.angle]) * 1e6)
    np.testing.assert_allclose(np.asarray(at_solution), J, rtol=0, atol=1e-5 * np.abs(J).max())
    h = 1e-2  # mm / mrad: the response is nearly linear, and the solves' own error stays far below h J
    # reverse mode (one transposed solve) gives the same derivatives as the forward tangents
    weights = jnp.linspace(-1.0, 1.0, J.shape[0])
    g = np.asarray(jax.grad(lambda t: outputs(t) @ weights)(theta0))
    np.testing.assert_allclose(g, J.T @ np.asarray(weights), rtol=0, atol=1e-5 * np.abs(g).max())
    scale = np.max(np.abs(J))  # the tangents against the Jacobian's own size (a component the
    assert scale > 1.0  # machine hardly feels has a column near zero, which relative terms cannot judge)
    for k in range(space.size):
        e = jnp.zeros(space.size).at[k].set(h)
        fd = (np.asarray(outputs(theta0 + e)) - np.asarray(outputs(theta0 - e))) / (2 * h)
        np.testing.assert_allclose(J[:, k], fd, rtol=0, atol=1e-5 * scale)


def test_steady_walk_rate_matches_an_open_loop_run(machine):
    """The open-loop machine's walk, solved as a fixed point up to a uniform lateral drift, equals
    the slope of the belt's lateral position in a long open-loop run after its transient."""
    model, opts = machine
    walk = steady_walk(model, opts.solver, dt=opts.dt)
    assert bool(walk.converged)
    open_loop = model.replace(control=None)
    _, tr = jb.simulate(open_loop, opts.solver, n_steps=3000, dt=opts.dt)
    t, v = np.asarray(tr.t), np.asarray(tr.tracer_v).mean(axis=1)
    late = t > 40.0
    slope = np.polyfit(t[late], v[late], 1)[0]
    assert abs(slope) > 1e-7
    np.testing.assert_allclose(float(walk.walk_rate), slope, rtol=0.01)


def test_a_walking_machine_has_no_stationary_steady_state(machine):
    model, opts = machine
    with pytest.raises(ValueError, match="walks"):
        steady_state(model.replace(control=None), opts.solver, dt=opts.dt)


def test_mass_transport_preconditioner_changes_the_iterations_not_the_answer(machine, steady):
    """GMRES with the mass-transport preconditioner and without it find the same steady state (to
    the residual tolerance's reach: 1e-6 µm of residual moves the slow lateral modes by up to
    ~1e-4 µm, within 1e-3 µm of each other here), the preconditioned one in fewer Krylov iterations."""
    model, opts = machine
    plain = steady_state(model, opts.solver, dt=opts.dt, precondition=False)
    assert bool(plain.converged) and bool(steady.converged)
    np.testing.assert_allclose(np.asarray(steady.tracer_v), np.asarray(plain.tracer_v), rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.asarray(steady.tracer_u), np.asarray(plain.tracer_u), rtol=0, atol=1e-9)
    assert int(steady.krylov_iterations) < int(plain.krylov_iterations)


def test_steady_walk_tangents_at_the_solution_equal_central_differences(machine):
    """:func:`jaxbelt.steady.steady_tangents` of the open-loop machine's steady walk rate (tangent
    solves at the known walk, no Newton) equal central differences of converged walk solves."""
    model, opts = machine
    opened = model.replace(control=None)
    space = parameter_space(model, "idle:dz,drive:ay")
    idx = jnp.asarray(space.chi_index, jnp.int32)
    configure = lambda t: opened.replace(chi_static=opened.chi_static.at[idx].add(t))  # noqa: E731
    theta0 = jnp.zeros(space.size)
    walk = steady_walk(opened, opts.solver, dt=opts.dt)
    J = np.asarray(steady_tangents(configure, theta0, walk, opts.solver, dt=opts.dt,
                                   outputs=lambda m, state, rate: rate))
    h = 1e-6  # m / rad: the walk rate is linear in the misalignment far beyond this
    rate = lambda t: float(steady_walk(configure(t), opts.solver, dt=opts.dt, tol=1e-9).walk_rate)  # noqa: E731
    fd = np.array([(rate(theta0.at[k].set(h)) - rate(theta0.at[k].set(-h))) / (2 * h) for k in range(space.size)])
    scale = np.abs(fd).max()  # the tilt walks the belt; the axial shift hardly does (its entry is solver noise)
    assert scale > 1e-3
    np.testing.assert_allclose(J, fd, rtol=0, atol=1e-5 * scale)


def test_solve_with_tangents_equals_solve_then_tangents(machine, steady):
    """:func:`jaxbelt.steady.steady_with_tangents` (Newton and the tangent solves in one loop on one
    linearisation) gives :func:`steady_state`'s solution and :func:`steady_tangents`' derivatives at
    it, for the steered machine and for the open-loop machine's walk rate; asked for no tangents
    (the same compiled program) it is the solve alone."""
    model, opts = machine
    space = parameter_space(model, "idle:dz,drive:ay")
    theta0 = jnp.zeros(space.size)
    idx = jnp.asarray(space.chi_index, jnp.int32)
    directions = jnp.zeros((space.size, model.chi_static.size)).at[jnp.arange(space.size), idx].set(1.0)
    s, J = steady_with_tangents(model, opts.solver, dt=opts.dt, directions=directions)
    assert bool(s.converged) and int(s.newton_steps) == int(steady.newton_steps)
    np.testing.assert_allclose(np.asarray(s.tracer_v), np.asarray(steady.tracer_v), rtol=0, atol=1e-12)
    configure = lambda t: model.replace(chi_static=model.chi_static.at[idx].add(t))  # noqa: E731
    tracers = lambda m, state, rate: jb.timeloop.tracer_values(m, state.u)  # noqa: E731
    J_at = np.asarray(jnp.concatenate(steady_tangents(configure, theta0, steady, opts.solver, dt=opts.dt,
                                                      outputs=tracers)))
    J = np.asarray(jnp.concatenate(J[:2]))
    assert np.abs(J_at).max() > 1e-3
    np.testing.assert_allclose(J, J_at, rtol=0, atol=1e-6 * np.abs(J_at).max())
    alone, none = steady_with_tangents(model, opts.solver, dt=opts.dt, directions=directions, n_tangents=0)
    assert np.all(np.isnan(np.asarray(none[1])))
    np.testing.assert_array_equal(np.asarray(alone.tracer_v), np.asarray(s.tracer_v))
    opened = model.replace(control=None)
    w, Jw = steady_with_tangents(opened, opts.solver, dt=opts.dt, directions=directions)
    walk = steady_walk(opened, opts.solver, dt=opts.dt)
    np.testing.assert_allclose(float(w.walk_rate), float(walk.walk_rate), rtol=1e-6)
    walk_of = lambda t: opened.replace(chi_static=opened.chi_static.at[idx].add(t))  # noqa: E731
    Jw_at = np.asarray(steady_tangents(walk_of, theta0, walk, opts.solver, dt=opts.dt, outputs=lambda m, state, rate: rate))
    np.testing.assert_allclose(np.asarray(Jw[-1]), Jw_at, rtol=0, atol=1e-6 * np.abs(Jw_at).max())


def test_solve_with_tangents_refuses_directions_it_cannot_take(machine):
    model, opts = machine
    q = model.chi_static.size
    with pytest.raises(ValueError, match="n_tangents = 3: must lie in 0..2"):
        steady_with_tangents(model, opts.solver, dt=opts.dt, directions=jnp.zeros((2, q)), n_tangents=3)
    with pytest.raises(ValueError, match=r"must be \(k, %d\)" % q):
        steady_with_tangents(model, opts.solver, dt=opts.dt, directions=jnp.zeros((2, q + 1)))
