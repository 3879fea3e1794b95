"""Gradients through the whole run match central finite differences.

Run lengths are whole numbers of the scan's checkpoint chunks (``⌈√n⌉`` steps: 9, 30, 56, 400)
wherever the test does not need padding, so that no slot of the loop branches around the step
(``jaxbelt.loop_plan.loop_plan``; the compiled gradient holds one copy of the step's forward,
recomputation and adjoint either way)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.linalg import bordered_solve, join
from jaxbelt.linalg.bordered import factor_solve_transposed, factorise
from helpers import load, scene_with, random_bordered


@pytest.fixture(scope="module")
def loaded():
    return load("two-roller-1d-idle-translated")


def _metric(loaded, translation, n_steps=56):
    model, opts = loaded
    m = jb.with_misalignment(model, translation=translation)
    _, tr = jb.simulate(m, opts.solver, n_steps=n_steps, dt=opts.dt)
    return jnp.mean(tr.tracer_u**2) * 1e6 + jnp.mean(tr.tracer_u[-1]) * 1e3


@pytest.mark.parametrize("k", [0, 1])
def test_grad_wrt_roller_translation_matches_central_differences(loaded, k):
    """Slow (programs of its own). Fast: case 1d-drive-idle of
    test_grad_wrt_drive_idle_tension_rollers_matches_central_differences checks the x translation
    of both rollers against central differences (and
    test_checkpointed_scan_changes_neither_outputs_nor_gradients differentiates through
    ``with_misalignment(translation=…)`` in 1D)."""
    t0 = jnp.array([0.0, 1e-3])
    g = jax.grad(lambda t: _metric(loaded, t))(t0)[k]
    h = 1e-7
    e = jnp.zeros(2).at[k].set(h)
    fd = (_metric(loaded, t0 + e) - _metric(loaded, t0 - e)) / (2 * h)
    assert abs(float(g - fd)) / abs(float(fd)) < 1e-5


def test_grad_through_eliminated_and_naive():
    """Reverse mode through the eliminated integrator (dense condensation, ``jnp.linalg.solve``)
    gives the direct one's gradient. The direct gradient is case 1d-drive-idle-kept-interior of
    test_grad_wrt_drive_idle_tension_rollers_matches_central_differences (the same program and
    point; checked there against central differences)."""
    model, opts = load("two-roller-1d")
    chi0 = _fd_point(model)
    g_direct = jax.jit(jax.grad(_tracer_metric(model, opts.dt, 56, "kept-interior")))(chi0)
    g_elim = jax.jit(jax.grad(_tracer_metric(model, opts.dt, 56, integrator="eliminated")))(chi0)
    assert float(jnp.max(jnp.abs(g_direct - g_elim))) < 1e-8 * float(jnp.max(jnp.abs(g_direct)))


@pytest.fixture(scope="module")
def model2d():
    return load(scene_with(lambda d: d["mesh"].update(n_eta=3), "three-roller"))


def _metric2d(loaded, chi, n_steps=9):
    model, opts = loaded
    m = model.replace(chi_static=chi)
    _, tr = jb.simulate(m, opts.solver, n_steps=n_steps, dt=opts.dt)
    return jnp.mean(tr.tracer_u[-1]) * 1e3 + jnp.sum(tr.tracer_v**2) * 1e6 + jnp.mean(tr.tracer_v) * 1e3


@pytest.mark.parametrize("dof", [0, 1, 2, 3, 4])
def test_grad_2d_wrt_each_misalignment_component(model2d, dof):
    """Roller 2's dx, dy, dz, αx, αy (index 6 + dof) around a misaligned configuration.

    Slow (programs of its own). Fast: case 2d-tension of
    test_grad_wrt_drive_idle_tension_rollers_matches_central_differences checks every translation
    and rotation of a drive, a tension and an idle roller in 2D against central differences."""
    chi0 = model2d[0].chi_static.at[1].set(1e-3).at[9].set(3e-4).at[14].set(1e-3)
    k = 6 + dof
    g = jax.grad(lambda c: _metric2d(model2d, c))(chi0)[k]
    h = 1e-7 if dof < 3 else 1e-8
    e = jnp.zeros_like(chi0).at[k].set(h)
    fd = (_metric2d(model2d, chi0 + e) - _metric2d(model2d, chi0 - e)) / (2 * h)
    assert abs(float(g - fd)) <= 1e-5 * abs(float(fd)) + 1e-12


# --- the solve's own adjoint and the checkpointed scan ---------------------------------------



def _rel(x, ref):
    return float(jnp.linalg.norm(x - ref) / jnp.linalg.norm(ref))


@pytest.mark.parametrize("method", ["thomas", "cyclic-reduction"])
def test_adjoint_solve_equals_dense_transposed_solve(method):
    """The transposed solve with A's factors, and reverse mode through ``bordered_solve`` (its
    right-hand-side cotangent is ``A⁻ᵀ x̄``), equal a dense ``jnp.linalg`` solve with ``Aᵀ``."""
    A, cb, cr = random_bordered(9, 4, 6)
    ref = jnp.linalg.solve(A.to_dense().T, join(cb, cr))
    # jit-compiled, as inside a run (one program each, not a few hundred op-by-op compilations)
    transposed = jax.jit(lambda A, cb, cr: join(*factor_solve_transposed(factorise(A, method), cb, cr)))
    assert _rel(transposed(A, cb, cr), ref) < 1e-12

    @jax.jit
    def reverse_mode(A, cb, cr):
        _, pullback = jax.vjp(lambda rb, rr: bordered_solve(A, rb, rr, method), jnp.zeros_like(cb), jnp.zeros_like(cr))
        return join(*pullback((cb, cr)))

    assert _rel(reverse_mode(A, cb, cr), ref) < 1e-12


def test_reverse_mode_reuses_the_factors():
    """The pullback of ``bordered_solve`` neither refactorises nor differentiates the
    factorisation: outside its transposed ``custom_linear_solve`` (the transposed sweeps with the
    forward pass's factors) there is no sequential sweep, LU or triangular solve, only the
    matrix cotangent's products. Differentiating ``factor_solve(factorise(A))`` has them all."""
    from jaxbelt.linalg.bordered import factor_solve

    A, rb, rr = random_bordered(9, 4, 6)

    def pullback_jaxpr(f):
        """The pullback's jaxpr, traced abstractly (nothing is compiled or run)."""
        out = {}

        def trace(A, rb):
            y, pullback = jax.vjp(f, A, rb)
            out["jaxpr"] = jax.make_jaxpr(pullback)(y).jaxpr
            return y

        jax.eval_shape(trace, A, rb)
        return out["jaxpr"]

    def outside_solves(f):
        names = set()

        def walk(jaxpr):
            for eqn in jaxpr.eqns:
                names.add(eqn.primitive.name)
                if eqn.primitive.name != "custom_linear_solve":
                    for p in eqn.params.values():
                        for sub in p if isinstance(p, (tuple, list)) else (p,):
                            sub = getattr(sub, "jaxpr", sub)
                            if hasattr(sub, "eqns"):
                                walk(sub)

        walk(pullback_jaxpr(f))
        return names

    factorisation = {"scan", "while", "lu", "triangular_solve"}
    names = outside_solves(lambda A, rb: bordered_solve(A, rb, rr, "thomas"))
    assert "custom_linear_solve" in names and not names & factorisation
    assert outside_solves(lambda A, rb: factor_solve(factorise(A, "thomas"), rb, rr)) & factorisation


def _coarse_2d(name):
    return load(scene_with(lambda d: d.setdefault("mesh", {}).update(n_eta=3), name))


# scene, steps, chi_static components with an effect (drive, idle, tension roller; translations
# and rotations), components of dynamic DOFs (no static effect: zero gradient)
_FD_CASES = {
    "1d-drive-idle": (lambda: load("two-roller-1d"), 56, [0, 1, 2], [3]),
    "1d-tension": (lambda: load("two-roller-1d-tension"), 56, [0, 1], [2, 3]),
    # roller 1 drive (0-4), roller 2 tension (7-10; dx dynamic), roller 3 idle (12-16); α_z: 5, 11, 17
    "2d-tension": (lambda: _coarse_2d("three-roller-tension"), 30, [0, 1, 2, 3, 4, 7, 8, 9, 10, 12, 13, 14, 15, 16],
                   [6, 11, 17]),
}


def _tracer_metric(model, dt, n_steps, solver=None, integrator="direct"):
    def metric(chi):
        m = model.replace(chi_static=chi)
        _, tr = jb.simulate(m, jb.make_solver(integrator, solver), n_steps=n_steps, dt=dt)
        v = 0.0 if tr.tracer_v is None else jnp.sum(tr.tracer_v**2) * 1e6 + jnp.mean(tr.tracer_v) * 1e3
        return jnp.mean(tr.tracer_u[-1]) * 1e3 + jnp.sum(tr.tracer_u[-1] ** 2) * 1e6 + v

    return metric


def _fd_point(model):
    """A random misalignment around the scene's own (1 mm or mrad translations and rotations
    where a roller has them, 0.3 mm otherwise)."""
    d = len(model.dofs)
    scale = np.where(np.arange(model.chi_static.size) % d < min(d - 1, 3), 1e-3, 3e-4)
    return model.chi_static + jnp.asarray(np.random.default_rng(0).uniform(-1, 1, model.chi_static.size) * scale)


_FD_PARAMS = [pytest.param(case, solver, id=f"{case}-{solver}")
              for solver in ("kept-interior", "reuse") for case in _FD_CASES]


@pytest.mark.parametrize("case,solver", _FD_PARAMS)
def test_grad_wrt_drive_idle_tension_rollers_matches_central_differences(case, solver):
    """Reverse mode through the whole run (custom adjoint solve, checkpointed scan) against
    central differences (h = 1e-6 m or rad) around a random misalignment, every component.
    The factorisation-reuse solver's cases are slow; fast, the kept-interior solver's cases here and,
    for reverse mode through the reuse solver in 2D, the shared study of design/conftest.py (reuse) in
    design/test_sensitivity.py: test_response_is_linear_in_small_misalignments (its forward-mode
    Jacobian against full runs) and test_jacobian_forward_matches_the_reverse_gradient (its
    reverse-mode gradient against that Jacobian)."""
    make, n_steps, active, inactive = _FD_CASES[case]
    model, opts = make()
    chi0 = _fd_point(model)
    metric = _tracer_metric(model, opts.dt, n_steps, solver)
    g = jax.jit(jax.grad(metric))(chi0)
    f = jax.jit(metric)
    h = 1e-6
    gmax = float(jnp.max(jnp.abs(g)))
    for k in active + inactive:
        e = jnp.zeros_like(chi0).at[k].set(h)
        fd = float((f(chi0 + e) - f(chi0 - e)) / (2 * h))
        if k in active:
            assert abs(float(g[k]) - fd) < 1e-6 * abs(fd), (k, float(g[k]), fd)
        else:
            assert abs(float(g[k])) <= 1e-12 * gmax and abs(fd) <= 1e-9 * gmax, (k, float(g[k]), fd)


def test_checkpointed_scan_changes_neither_outputs_nor_gradients():
    """Chunked ``jax.checkpoint`` with ``every = 3`` and a tail of 2 steps: 1-step chunks (nested
    inside each record interval, the tail's padded interval too) give the same trajectory and
    gradient as no checkpointing, 6-step chunks (2 records each, the last chunk padded) the same
    trajectory."""
    model, opts = load("two-roller-1d")
    state = jb.initial_state(model)

    def metric(t, checkpoint):
        _, tr = jb.simulate(jb.with_misalignment(model, translation=t), opts.solver, n_steps=17, dt=opts.dt,
                            saveat=jb.SaveAt(every=3), adjoint=jb.Checkpointed(checkpoint), y0=state)
        return jnp.sum(tr.tracer_u**2) * 1e6 + jnp.mean(tr.roller_velocity), tr

    def check(tr, ref):
        for a, b in zip(jax.tree.leaves(tr), jax.tree.leaves(ref)):
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-13, atol=1e-13 * float(jnp.max(jnp.abs(b))))

    t0 = jnp.array([0.0, 1e-3])
    value_and_grad = lambda checkpoint: jax.jit(jax.value_and_grad(lambda t: metric(t, checkpoint), has_aux=True))(t0)
    (_, ref), ref_g = value_and_grad(0)
    assert ref.t.shape == (5,)
    (_, tr), g = value_and_grad(1)
    check(tr, ref)
    np.testing.assert_allclose(np.asarray(g), np.asarray(ref_g), rtol=1e-10)
    check(metric(t0, 6)[1], ref)


def test_checkpointing_bounds_reverse_mode_memory():
    """XLA's temporary memory for the gradient of a 400-step run: the checkpointed scan (20-step
    chunks) needs a fraction of what storing every step's residuals takes."""
    model, opts = load("two-roller-1d")

    def temp_bytes(checkpoint):
        def metric(chi):
            m = model.replace(chi_static=chi)
            _, tr = jb.timeloop.run(m, jb.DirectBackwardEuler(), jb.initial_state(m), opts.dt, 400, jb.SaveAt(),
                                    checkpoint)
            return jnp.sum(tr.tracer_u[-1] ** 2)

        return jax.jit(jax.grad(metric)).lower(model.chi_static).compile().memory_analysis().temp_size_in_bytes

    assert temp_bytes(None) < temp_bytes(0) / 4
