"""The exact solver's kept interior: one interior factorisation per run, the border per step.

With the shift transport the belt's interior blocks of ``M + Δt² K`` never change; only the
tilt columns (lever arm ``z + v``) and, for dynamic tilts, their roller rows do
(:class:`jaxbelt.integrators.KeptInterior`). Checked against a full factorisation of
every step's matrix and against dense solves, forward and in reverse mode."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.integrators import DirectBackwardEuler, KeptInterior, StepOperator, Structured
from jaxbelt.integrators.linear import lever_columns
from jaxbelt.linalg import BorderedBlockCyclic, join
from jaxbelt.linalg.bordered import dense_solve, factor_solve, factorise, refactorise_border, scaled_schur
from jaxbelt.timeloop import run
from helpers import load, scene_fixtures, scene_with, solve_step


def FullFactorisation():
    """The exact solver without the kept interior: every step's matrix factored in full."""
    return DirectBackwardEuler(Structured())


def _random_bordered(rng, n=7, b=4, q=5):
    g = lambda *s: jnp.asarray(rng.normal(size=s))  # noqa: E731
    return BorderedBlockCyclic(diag=g(n, b, b) + 8 * jnp.eye(b), lower=g(n, b, b), upper=g(n, b, b),
                               C=g(n, b, q), D=g(n, q, b), E=g(q, q) + 8 * jnp.eye(q))


@pytest.mark.parametrize("method", ["thomas", "cyclic-reduction"])
def test_refactorise_border_is_the_exact_factorisation(method):
    rng = np.random.default_rng(3)
    A_ref = _random_bordered(rng)
    cols, rows = (1, 3), (0, 3)
    C = A_ref.C.at[:, :, jnp.asarray(cols)].add(jnp.asarray(rng.normal(size=(7, 4, 2))))
    D = A_ref.D.at[:, jnp.asarray(rows), :].add(jnp.asarray(rng.normal(size=(7, 2, 4))))
    A = BorderedBlockCyclic(A_ref.diag, A_ref.lower, A_ref.upper, C, D, A_ref.E)
    rb, rr = jnp.asarray(rng.normal(size=(7, 4))), jnp.asarray(rng.normal(size=5))

    @jax.jit
    def solves(A_ref, A, rb, rr):
        F_ref = factorise(A_ref, method)
        F = refactorise_border(A, F_ref, scaled_schur(A_ref, F_ref), cols, rows)
        return factor_solve(F, rb, rr), factor_solve(F_ref, rb, rr), dense_solve(A, rb, rr)

    x, x_ref_factors, x_dense = solves(A_ref, A, rb, rr)
    for a, b in zip(x, x_dense):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-11, atol=1e-12)
    # and the reference's factors alone would not do: the test can fail
    assert float(jnp.max(jnp.abs(x_ref_factors[0] - x_dense[0]))) > 1e-3


def walking_scene():
    """A small three-roller belt whose lever arms keep moving: a skewed roller with lateral
    transport (the belt walks), and a tension roller whose x-tilt is a dynamic, torque-loaded DOF
    (its roller row moves with the lever arm too)."""

    def mutate(d):
        d.setdefault("mesh", {}).update(n_eta=3)
        d.setdefault("solver", {}).update(lateral_transport=True)
        d.setdefault("variant", {}).setdefault("roller 2", {}).update(role="tension", force_n=[200.0, 0.0, 0.0],
                                                                    torque_nm=[0.5, 0.0, 0.0],
                                                                    rotation_mrad=[0.0, 0.0, 0.0])
        d["variant"].setdefault("roller 3", {}).update(rotation_mrad=[0.0, 2.0, 0.0])

    return scene_with(mutate, "three-roller-t72")


loaded, walking, dt = scene_fixtures(walking_scene)


def drifting_scene():
    """The walking belt with every tilt a prescribed DOF (no torque-loaded tension tilt): the
    lever arms keep moving, and the kept factors are border first."""

    def mutate(d):
        d.setdefault("mesh", {}).update(n_eta=3)
        d.setdefault("solver", {}).update(lateral_transport=True)
        d.setdefault("variant", {}).setdefault("roller 3", {}).update(rotation_mrad=[0.0, 2.0, 0.0])

    return scene_with(mutate, "three-roller-t72")


@pytest.fixture(scope="module")
def drifting():
    return load(drifting_scene())[0]


@pytest.fixture(scope="module")
def moved(walking, dt):
    """The state after 4 steps: the lever arms have moved away from the reference's."""
    return jax.jit(lambda m: run(m, FullFactorisation(), jb.initial_state(m), dt, 4)[0])(walking)


def test_lever_columns_and_dynamic_rows(walking):
    cols, rows = lever_columns(walking)
    d = len(walking.dofs)
    assert cols == tuple(j * d + walking.dofs.index(a) for j in range(3) for a in ("ax", "ay"))
    assert rows == (d + walking.dofs.index("ax"),)  # roller 2's torque-loaded x tilt


@pytest.mark.reference
def test_kept_factors_solve_as_a_full_factorisation(walking, dt, moved):
    """At a state whose lever arms have moved, the kept interior with the step's border solves
    the step's matrix as its full factorisation and a dense solve do; the reference's factors
    alone would not."""
    s = moved
    rng = np.random.default_rng(4)
    rb = jnp.asarray(rng.normal(size=(walking.n_xi, walking.block)))
    rr = jnp.asarray(rng.normal(size=walking.n_roller_dofs))

    @jax.jit
    def solves(m, s, rb, rr):
        op = StepOperator(m, s.m_e, jb.assembly.roller_R(m, s.u), dt)
        ref = KeptInterior().reference(m, s, dt)
        kept = KeptInterior().compute(KeptInterior().init(op, ref), rb, rr)
        full = Structured().compute(Structured().init(op), rb, rr)
        return kept, full, dense_solve(op.matrix(), rb, rr), factor_solve(ref.F, rb, rr)

    kept, full, dense, frozen = (join(*x) for x in solves(walking, s, rb, rr))
    scale = float(jnp.max(jnp.abs(dense)))
    np.testing.assert_allclose(np.asarray(kept), np.asarray(full), rtol=0, atol=1e-11 * scale)
    np.testing.assert_allclose(np.asarray(kept), np.asarray(dense), rtol=0, atol=1e-10 * scale)
    assert float(jnp.max(jnp.abs(frozen - dense))) > 1e-8 * scale  # the test can fail


def test_run_equals_a_full_factorisation_every_step(walking, dt):
    """The kept interior against the full factorisation of every step's matrix, over a run whose
    lever arms move."""
    n = 16
    s0 = jb.initial_state(walking)
    (s_full, tr_full), *kept = jax.jit(lambda s: [
        run(walking, i, s, dt, n) for i in (FullFactorisation(), DirectBackwardEuler(KeptInterior()))])(s0)
    scale_u = float(jnp.max(jnp.abs(s_full.u)))
    r = np.asarray(tr_full.roller_reaction)
    for s_kept, tr_kept in kept:
        np.testing.assert_allclose(np.asarray(s_kept.u), np.asarray(s_full.u), rtol=0, atol=1e-12 * scale_u)
        np.testing.assert_allclose(np.asarray(s_kept.chi), np.asarray(s_full.chi), rtol=0, atol=1e-13)
        np.testing.assert_allclose(np.asarray(tr_kept.roller_reaction), r, rtol=0, atol=1e-9 * np.max(np.abs(r)))
    # the lever arms did move (else the test could not tell the kept interior from a frozen matrix)
    assert float(jnp.max(jnp.abs(s_full.u[:, 1::2] - s0.u[:, 1::2]))) > 1e-7


@pytest.mark.parametrize("border", ["green", "sweep"])
def test_border_first_run_equals_a_full_factorisation_every_step(drifting, dt, border):
    """Prescribed tilts: the kept factors, border first (the default) or sweeping the tilt columns,
    against the full factorisation of every step's matrix over a run whose lever arms move, and
    reverse mode through the run against reverse mode through the full factorisation."""
    from jaxbelt.integrators.linear import border_first_possible

    assert border_first_possible(drifting)
    n = 16
    kept = DirectBackwardEuler(KeptInterior(border=border))
    s0 = jb.initial_state(drifting)

    def metric(integrator, rot):
        s, tr = run(jb.with_misalignment(drifting, rotation=rot), integrator, s0, dt, n)
        return jnp.sum(tr.tracer_v[-1] ** 2) + jnp.sum(s.chi ** 2), s

    rot = jnp.zeros((3, 3)).at[0, 0].set(3e-4)
    (_, s_kept), g_kept = jax.jit(jax.value_and_grad(lambda r: metric(kept, r), has_aux=True))(rot)
    (_, s_full), g_full = jax.jit(jax.value_and_grad(lambda r: metric(FullFactorisation(), r), has_aux=True))(rot)
    scale_u = float(jnp.max(jnp.abs(s_full.u)))
    np.testing.assert_allclose(np.asarray(s_kept.u), np.asarray(s_full.u), rtol=0, atol=1e-12 * scale_u)
    np.testing.assert_allclose(np.asarray(s_kept.chi), np.asarray(s_full.chi), rtol=0, atol=1e-13)
    np.testing.assert_allclose(np.asarray(g_kept), np.asarray(g_full), rtol=1e-9,
                               atol=1e-9 * float(jnp.max(jnp.abs(g_full))))
    assert float(jnp.max(jnp.abs(g_full))) > 0
    assert float(jnp.max(jnp.abs(s_full.u[:, 1::2] - s0.u[:, 1::2]))) > 1e-7  # the lever arms did move


def test_gradient_through_the_kept_interior(walking, dt, moved):
    """Reverse mode through one step (its adjoint solve is the transposed kept-interior solve)
    equals reverse mode through the full factorisation."""
    s = moved
    kept, full = DirectBackwardEuler(KeptInterior()), FullFactorisation()

    def metric(integrator, run_data, rot):
        solved = integrator.step(jb.with_misalignment(walking, rotation=rot), s, dt, run_data)
        return jnp.sum(solved.u[:, 1::2] ** 2) + jnp.sum(solved.chi ** 2)

    @jax.jit
    def grads(r):
        kept_data, full_data = kept.init(walking, s, dt), full.init(walking, s, dt)
        assert kept_data.linear is not None  # the run's kept interior (static: checked while tracing)
        return (jax.grad(lambda r: metric(kept, kept_data, r))(r), jax.grad(lambda r: metric(full, full_data, r))(r))

    rot = jnp.zeros((3, 3)).at[2, 1].set(2e-3)
    g_kept, g_full = grads(rot)
    np.testing.assert_allclose(np.asarray(g_kept), np.asarray(g_full), rtol=1e-9,
                               atol=1e-9 * float(jnp.max(jnp.abs(g_full))))
    assert float(jnp.max(jnp.abs(g_full))) > 0


def test_reuse_factors_come_from_the_start_state_of_the_run(walking, dt, moved):
    """:class:`jaxbelt.Reuse` factors the matrix of the state a run starts from (its ``init``,
    inside the run): without refinement, its first step from a state whose lever arms have moved
    is the exact step, and the same frozen solve with the factors of another state is not."""
    reuse = DirectBackwardEuler(jb.Reuse(refine=0))
    exact = solve_step(walking, FullFactorisation(), moved, dt)
    first = solve_step(walking, reuse, moved, dt)
    stale = jax.jit(lambda s0, s: reuse.step(walking, s, dt, reuse.init(walking, s0, dt)))(jb.initial_state(walking),
                                                                                          moved)
    scale = float(jnp.max(jnp.abs(exact.u_dot)))
    np.testing.assert_allclose(np.asarray(first.u_dot), np.asarray(exact.u_dot), rtol=0, atol=1e-11 * scale)
    np.testing.assert_allclose(np.asarray(first.chi), np.asarray(exact.chi), rtol=0, atol=1e-13)
    assert float(jnp.max(jnp.abs(stale.u_dot - exact.u_dot))) > 1e-9 * scale  # the test can fail


def test_source_transport_factors_every_step(walking, dt):
    s0 = jb.initial_state(walking)
    assert DirectBackwardEuler(KeptInterior(), transport="source").init(walking, s0, dt).linear is None
    assert DirectBackwardEuler(KeptInterior()).init(walking, s0, dt).linear is not None
    assert FullFactorisation().init(walking, s0, dt).linear is None


def test_stencil_product_equals_the_block_product(walking):
    from jaxbelt.assembly import free_belt_matvec, free_belt_stencil, stencil_matvec

    u = jnp.asarray(np.random.default_rng(0).normal(size=(walking.n_xi, walking.block)))
    S = free_belt_stencil(walking)
    ref = free_belt_matvec(walking, u)
    tol = 1e-13 * float(jnp.max(jnp.abs(ref)))
    np.testing.assert_allclose(np.asarray(stencil_matvec(S, u)), np.asarray(ref), rtol=0, atol=tol)
    cols = walking.contact_columns
    assert 0 < len(cols) < walking.n_xi
    np.testing.assert_allclose(np.asarray(stencil_matvec(S, u, cols)), np.asarray(ref)[np.asarray(cols)], rtol=0,
                               atol=tol)
    assert free_belt_stencil(jb.build_model(jb.load_scene("two-roller-1d"))) is None


def test_roller_loads_on_the_contact_columns_equal_the_full_product(walking, dt):
    from jaxbelt.timeloop import make_step

    s = jb.initial_state(walking)
    integ = DirectBackwardEuler(KeptInterior())
    r_on = jax.jit(lambda s: make_step(walking, integ, dt)(s)[1]["roller_reaction"])(s)
    full = walking.replace(contact_columns=None)
    r_all = jax.jit(lambda s: make_step(full, integ, dt)(s)[1]["roller_reaction"])(s)
    np.testing.assert_allclose(np.asarray(r_on), np.asarray(r_all), rtol=1e-10, atol=1e-9 * float(jnp.max(jnp.abs(r_all))))
    assert float(jnp.max(jnp.abs(r_all))) > 1.0  # the supports do carry load


def _random_interior(rng, breaks, b, w=None, shift=8.0):
    """Random diagonally dominant block-tridiagonal blocks ``(diag, lower, upper)`` (m, b, b) whose
    couplings vanish at the ``breaks`` (and beyond ``w`` diagonals off their main one, if given)."""
    m = len(breaks)
    i, j = np.indices((b, b))
    band = 1.0 if w is None else jnp.asarray(np.abs(i - j) <= w, float)
    mask = jnp.asarray(~breaks, float)[:, None, None]
    diag = jnp.asarray(rng.normal(size=(m, b, b)) + shift * np.eye(b))
    lower, upper = (jnp.asarray(rng.normal(size=(m, b, b))) * band * mask for _ in range(2))
    return diag, lower, upper


def test_chained_sweeps_equal_the_plain_ones_and_their_transpose():
    """Blocks with zero couplings break the chain: the rearranged sweeps give the same solve,
    and its transpose (the adjoint solve) equals the plain one's."""
    from jaxbelt.linalg.thomas import chain_thomas, chained_thomas_apply, thomas_apply, thomas_factor

    rng = np.random.default_rng(5)
    m, b = 11, 3
    breaks = np.zeros(m, bool)
    breaks[[0, 1, 4, 5, 9]] = True  # runs of single blocks, chains of lengths 3 and 4, a last chain of 2
    diag, lower, upper = _random_interior(rng, breaks, b, shift=6.0)
    r = jnp.asarray(rng.normal(size=(m, b, 2)))
    spec = jax.ShapeDtypeStruct(r.shape, r.dtype)
    wrong = breaks.copy()
    wrong[7] = True  # a coupled block declared free of couplings

    @jax.jit  # one program (op by op, the sweeps' small primitives compile one by one)
    def solves(diag, lower, upper, r):
        F = thomas_factor(diag, lower, upper)
        Fc = chain_thomas(F, breaks)
        tr = lambda f: jax.linear_transpose(f, spec)(r)[0]  # noqa: E731
        return (chained_thomas_apply(Fc, r), thomas_apply(F, r), tr(lambda x: chained_thomas_apply(Fc, x)),
                tr(lambda x: thomas_apply(F, x)), chained_thomas_apply(chain_thomas(F, wrong), r))

    x_c, x_p, tr_c, tr_p, x_wrong = solves(diag, lower, upper, r)
    np.testing.assert_allclose(np.asarray(x_c), np.asarray(x_p), rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(np.asarray(tr_c), np.asarray(tr_p), rtol=1e-13, atol=1e-13)
    # wrong breaks give a different answer: the test can fail
    assert float(jnp.max(jnp.abs(x_wrong - x_p))) > 1e-6


def test_banded_forward_sweep_equals_the_plain_sweeps_and_their_transpose():
    """A coupling that vanishes beyond ``w`` diagonals kept as its diagonals: the chained solve and
    its transpose equal the plain Thomas sweeps; a band declared too narrow drops entries and
    gives another answer."""
    from jaxbelt.linalg.thomas import chain_thomas, chained_thomas_apply, thomas_apply, thomas_factor

    rng = np.random.default_rng(7)
    m, b, w = 9, 6, 1
    breaks = np.zeros(m, bool)
    breaks[[0, 4]] = True
    diag, lower, upper = _random_interior(rng, breaks, b, w)
    r = jnp.asarray(rng.normal(size=(m, b, 3)))
    spec = jax.ShapeDtypeStruct(r.shape, r.dtype)

    @jax.jit
    def solves(diag, lower, upper, r):
        F = thomas_factor(diag, lower, upper)
        Fb = chain_thomas(F, breaks, band=w)
        tr = lambda f: jax.linear_transpose(f, spec)(r)[0]  # noqa: E731
        return (chained_thomas_apply(Fb, r), thomas_apply(F, r), tr(lambda x: chained_thomas_apply(Fb, x)),
                tr(lambda x: thomas_apply(F, x)), chained_thomas_apply(chain_thomas(F, breaks, band=0), r),
                Fb.f_L[0].shape, len(Fb.f_P))

    x_b, x_p, tr_b, tr_p, x_narrow, shape, n_dense = solves(diag, lower, upper, r)
    assert shape[-2:] == (2 * w + 1, b) and n_dense == 0  # the diagonals kept, no dense coupling blocks
    np.testing.assert_allclose(np.asarray(x_b), np.asarray(x_p), rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(np.asarray(tr_b), np.asarray(tr_p), rtol=1e-13, atol=1e-13)
    assert float(jnp.max(jnp.abs(x_narrow - x_p))) > 1e-6


def test_sweeps_restricted_to_the_columns_a_chain_can_see_equal_the_full_sweeps():
    """Right-hand-side columns non-zero on a few blocks only (as a tilt's column lives on its
    roller's columns): the chained sweeps restricted, chain by chain, to the columns that can
    reach it equal the full sweeps, banded or dense, batched by vmap and transposed."""
    from jaxbelt.linalg.thomas import chain_thomas, chained_thomas_apply, chained_thomas_apply_sparse, thomas_factor

    rng = np.random.default_rng(3)
    m, b, w = 14, 4, 1
    breaks = np.zeros(m, bool)
    breaks[[0, 1, 5, 6, 10]] = True  # three "rollers" (0-1, 5-6, 10) and the spans between them
    diag, lower, upper = _random_interior(rng, breaks, b, w)
    support = ((0, 1), (0,), (5, 6), (10,), (5,))
    r = np.zeros((2, m, b, len(support)))
    for c, sup in enumerate(support):
        for k in sup:
            r[:, k, :, c] = rng.normal(size=(2, b))
    r = jnp.asarray(r)
    spec = jax.ShapeDtypeStruct(r.shape[1:], r.dtype)

    @jax.jit
    def solves(diag, lower, upper, r):
        F = thomas_factor(diag, lower, upper)
        out = []
        for bw in (None, w):
            Fc = chain_thomas(F, breaks, band=bw)
            tr = lambda f: jax.linear_transpose(f, spec)(r[0])[0]  # noqa: E731
            out.append((jax.vmap(lambda x: chained_thomas_apply(Fc, x))(r),
                        jax.vmap(lambda x: chained_thomas_apply_sparse(Fc, x, support))(r),
                        tr(lambda x: chained_thomas_apply(Fc, x)), tr(lambda x: chained_thomas_apply_sparse(Fc, x, support))))
        return out

    for full, restricted, tr_full, tr_restricted in solves(diag, lower, upper, r):
        assert float(jnp.max(jnp.abs(full))) > 0.1
        np.testing.assert_allclose(np.asarray(restricted), np.asarray(full), rtol=0, atol=1e-14)
        # the transpose is another operator (it reads the right-hand side off the support too): compared on it
        sel = np.zeros(r.shape[1:], bool)
        for c, sup in enumerate(support):
            sel[list(sup), :, c] = True
        np.testing.assert_allclose(np.asarray(tr_restricted)[sel], np.asarray(tr_full)[sel], rtol=0, atol=1e-14)


def test_contact_structure_narrows_block_0s_columns_and_solves_exactly():
    """With the roller columns known, ``T⁻¹`` of block 0's border columns is kept on the free
    spans next to block 0 only, and the roller rows' couplings on the roller columns and their
    neighbours only; the solve, its transpose and a border refactorisation with it still equal
    dense solves."""
    from jaxbelt.linalg.bordered import factor_solve_transposed, with_chained_interior

    rng = np.random.default_rng(11)
    n, b, q = 14, 3, 4
    contact = (0, 1, 5, 6, 10)  # belt columns on rollers: their rows couple to no belt column
    on = np.isin(np.arange(n), contact)[:, None, None]
    # the roller rows reach the contact columns and their neighbours only (Rᵀ K_f): 0, 1, 2, 4..7, 9..11, 13
    near = (np.roll(on, 1, 0) | on | np.roll(on, -1, 0)).reshape(n, 1, 1)
    g = lambda *s: jnp.asarray(rng.normal(size=s))  # noqa: E731
    A = BorderedBlockCyclic(diag=g(n, b, b) + 8 * jnp.eye(b), lower=jnp.where(on, 0.0, g(n, b, b)),
                            upper=jnp.where(on, 0.0, g(n, b, b)), C=g(n, b, q), D=jnp.where(near, g(n, q, b), 0.0),
                            E=g(q, q) + 8 * jnp.eye(q))
    rb, rr = g(n, b), g(q)
    cols, rows = (1, 2), (2,)
    A2 = BorderedBlockCyclic(A.diag, A.lower, A.upper, A.C.at[:, :, jnp.asarray(cols)].add(g(n, b, 2)),
                             A.D.at[:, jnp.asarray(rows), :].add(jnp.where(near, g(n, 1, b), 0.0)), A.E)

    @jax.jit  # one program (op by op, the many small sweeps' primitives compile one by one)
    def solves(A, A2, rb, rr):
        F = with_chained_interior(factorise(A, "thomas"), contact)
        F2 = refactorise_border(A2, F, scaled_schur(A, F), cols, rows)
        rows0.append((F.y_G0_rows, F.H_blocks))  # static: recorded while tracing
        return (factor_solve(F, rb, rr), factor_solve_transposed(F, rb, rr), factor_solve(F2, rb, rr),
                dense_solve(A, rb, rr), dense_solve(A.transpose(), rb, rr), dense_solve(A2, rb, rr))

    rows0 = []
    x, x_t, x2, d, d_t, d2 = solves(A, A2, rb, rr)
    # interior blocks 0..12 are columns 1..13; columns 11..13 (blocks 10..12) form the span before column 0;
    # the roller rows are kept on the roller columns and their neighbours only (columns 3, 8, 12 dropped)
    assert rows0 == [((10, 11, 12), (0, 1, 3, 4, 5, 6, 8, 9, 10, 12))]
    for got, want in ((x, d), (x_t, d_t), (x2, d2)):
        for a, b_ in zip(got, want):
            np.testing.assert_allclose(np.asarray(a), np.asarray(b_), rtol=1e-11, atol=1e-12)
