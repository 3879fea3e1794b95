"""The linear solvers' lineax shape: ``init`` → ``compute`` solves ``A x = r`` and
``compute(transpose(state))`` solves ``Aᵀ x = r``, each against a dense solve of the assembled
step matrix, on a 1D and a coarse 2D belt with a tilted roller (the lever arms in ``A``)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.assembly import roller_R
from jaxbelt.integrators import StepOperator, make_linear_solver
from jaxbelt.integrators.linear import lever_columns
from jaxbelt.linalg import join, split
from jaxbelt.registry import LINEAR_SOLVERS

from helpers import COARSE_2D_TWO_ROLLER, load


def _case(kind):
    if kind == "1d":
        model, opts = load("two-roller-1d")
    else:
        model, opts = load(jb.scene_from_dict(__import__("tomllib").loads(
            COARSE_2D_TWO_ROLLER + "[time]\ndt_s = 0.005\nt_end_s = 0.05\n")))
        model = jb.with_misalignment(model, rotation=jnp.zeros((model.n_rollers, 3)).at[1, 0].set(2e-4))
    state = jb.initial_state(model)
    # a state off the reference: the lever arms z + v of the tilts differ from the model's
    state = state.__class__(u=state.u + 1e-5 * jnp.sin(jnp.arange(state.u.size)).reshape(state.u.shape),
                            u_dot=state.u_dot, chi=state.chi, chi_dot=state.chi_dot, m_e=state.m_e, step=state.step)
    dt = jnp.asarray(opts.dt)
    return model, state, dt


@pytest.fixture(scope="module")
def case_1d():
    return _case("1d")


@pytest.fixture(scope="module")
def case_2d():
    return _case("2d")


@pytest.fixture(scope="module", params=["1d", "2d"])
def step_case(request):
    return request.getfixturevalue(f"case_{request.param}")


@eqx.filter_jit
def solve_both_ways(solver, model, state, dt, r):
    """``(A⁻¹ r, A⁻ᵀ r)`` with ``solver`` (one compiled program per solver and belt)."""
    reference = solver.reference(model, jb.initial_state(model), dt, "shift")
    R = roller_R(model, state.u, on_rollers=solver.uses_roller_columns(reference))
    op = StepOperator(model, state.m_e, R, dt)
    st = solver.init(op, reference)
    r_b, r_r = split(r, model.n_xi, model.block)
    return join(*solver.compute(st, r_b, r_r)), join(*solver.compute(solver.transpose(st), r_b, r_r)), \
        op.matrix().to_dense()


# In 2D the solvers that keep factors across lever-arm changes; the others factor the step's own
# matrix as in 1D (their 2D runs are checked by the integrator tests).
SOLVER_CASES = [("1d", name) for name in LINEAR_SOLVERS] + [("2d", "kept-interior"), ("2d", "reuse")]


@pytest.mark.parametrize("kind, name", SOLVER_CASES)
def test_compute_and_transpose_match_dense(request, kind, name):
    model, state, dt = request.getfixturevalue(f"case_{kind}")
    r = np.random.default_rng(0).normal(size=model.n_unknowns)
    x, xT, A = (np.asarray(a) for a in solve_both_ways(make_linear_solver(name), model, state, dt, jnp.asarray(r)))
    # reuse keeps the start state's factors: exact where the step matrix is the start's (1D), else
    # to the relative change of the lever arms (1e-5 m on ~10 mm, no refinement by default)
    tol = 1e-3 if name == "reuse" and model.kind == "2d" else 1e-9
    for got, M in ((x, A), (xT, A.T)):
        want = np.linalg.solve(M, r)
        np.testing.assert_allclose(got, want, rtol=tol, atol=tol * np.abs(want).max())


def test_lever_columns_are_the_tilts_in_2d(step_case):
    model = step_case[0]
    cols, rows = lever_columns(model)
    if model.kind == "1d":
        assert cols == () and rows == ()
    else:
        d = len(model.dofs)
        assert [model.dofs[c % d] for c in cols] == ["ax", "ay"] * model.n_rollers
        assert set(rows) <= set(cols)



def test_chained_sweeps_batch_under_vmap():
    """The chained Thomas sweeps (the kept and frozen factors' interior) under ``vmap`` over the
    factors themselves, chains of equal length run side by side (2-D block-index tables): each
    member equals its own rearrangement and the plain Thomas solve."""
    from jaxbelt.linalg.thomas import chain_thomas, chained_thomas_apply, thomas_apply, thomas_factor

    rng = np.random.default_rng(1)
    m, b, k = 12, 3, 2
    breaks = np.zeros(m, bool)
    breaks[[0, 4, 8]] = True  # three chains of four blocks; a break block couples to no neighbour
    keep = ~breaks[None, :, None, None]
    diag = jnp.asarray(rng.normal(size=(2, m, b, b)) + 8 * np.eye(b))
    lower = jnp.asarray(rng.normal(size=(2, m, b, b)) * keep)
    upper = jnp.asarray(rng.normal(size=(2, m, b, b)) * keep)
    rhs = jnp.asarray(rng.normal(size=(2, m, b, k)))

    def chained(d, lo, up, r):
        return chained_thomas_apply(chain_thomas(thomas_factor(d, lo, up), breaks), r)

    batched = jax.jit(jax.vmap(chained))(diag, lower, upper, rhs)
    factors = jax.vmap(thomas_factor)(diag, lower, upper)  # batched factors into the rearrangement alone
    rearranged = jax.jit(jax.vmap(lambda F: chain_thomas(F, breaks).f_P))(factors)
    for i in range(2):
        one = chain_thomas(jax.tree.map(lambda a: a[i], factors), breaks).f_P
        for got, want in zip(rearranged, one):
            np.testing.assert_allclose(np.asarray(got[i]), np.asarray(want), rtol=1e-12)
        plain = thomas_apply(thomas_factor(diag[i], lower[i], upper[i]), rhs[i])
        np.testing.assert_allclose(np.asarray(batched[i]), np.asarray(plain), rtol=1e-10, atol=1e-12)


def test_reuse_runs_under_vmap_over_misalignments(step_case):
    """Each configuration factors its own first step inside the batched run; in 2D a tilt changes
    the factors, so the chained interior's block gathers are batched too."""
    model, _, dt = step_case
    solver = jb.DirectBackwardEuler(jb.Reuse())
    d = len(model.dofs)
    k = d + model.dofs.index("ax") if "ax" in model.dofs else 0  # roller 2's tilt in 2D; a shift in 1D
    chis = jnp.stack([model.chi_static, model.chi_static.at[k].add(1e-4 if "ax" in model.dofs else 1e-5)])

    def last_tracers(chi):
        _, tr = jb.simulate(model.replace(chi_static=chi), solver, n_steps=3, dt=dt, check=False)
        return tr.tracer_u[-1]

    batched = jax.jit(jax.vmap(last_tracers))(chis)
    one = jax.jit(last_tracers)(chis[1])
    np.testing.assert_allclose(np.asarray(batched[1]), np.asarray(one), rtol=1e-12, atol=1e-15)
