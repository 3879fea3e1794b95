"""Tension stiffening: the initial-stress stiffness against scikit-fem and a tensioned beam, and
its effect (none without tension; stiffer lateral response with it)."""

import jax.numpy as jnp
import numpy as np
import pytest
from helpers import scene_with

import jaxbelt as jb
from jaxbelt.elements import quad_stiffness
from jaxbelt.prestress import quad_geometric_stiffness


def test_geometric_stiffness_equals_scikit_fem():
    skfem = pytest.importorskip("skfem")

    ell, w, t = 0.03, 0.02, 3e-4
    sx, sz, txz = 2.0e6, -3.0e5, 4.0e5
    m = skfem.MeshQuad(np.array([[0.0, ell, ell, 0.0], [0.0, 0.0, w, w]]), np.array([[0], [1], [2], [3]]))
    basis = skfem.Basis(m, skfem.ElementQuad1(), intorder=3)

    @skfem.BilinearForm
    def geo(u, v, _):
        g, h = u.grad, v.grad
        return t * (sx * g[0] * h[0] + sz * g[1] * h[1] + txz * (g[0] * h[1] + g[1] * h[0]))

    ref = geo.assemble(basis).toarray()
    # skfem's node order (0,0),(ℓ,0),(ℓ,w),(0,w) → ours (i,j),(i,j+1),(i+1,j),(i+1,j+1) with x along ℓ
    perm = [0, 3, 1, 2]
    sig = jnp.tile(jnp.array([sx, sz, txz]), (4, 1))
    K = np.asarray(quad_geometric_stiffness(ell, w, sig, t))
    np.testing.assert_allclose(K[0::2, 0::2], ref[np.ix_(perm, perm)], rtol=1e-12, atol=1e-12 * np.abs(ref).max())
    np.testing.assert_allclose(K[1::2, 1::2], K[0::2, 0::2])
    assert np.all(K[0::2, 1::2] == 0)


def _strip_deflection(T, L=2.0, w=0.02, t=3e-4, E=2.5e9, nx=200, nz=3, P=1.0):
    """Midspan lateral deflection of a clamped–clamped strip under tension T and a lateral point
    load P, assembled from jaxbelt's element matrices (plane stress + initial stress)."""
    nu = 0.0
    ell, h = L / nx, w / (nz - 1)
    Ke = np.asarray(quad_stiffness(ell, h, E, nu, t))
    Kg = np.asarray(quad_geometric_stiffness(ell, h, jnp.tile(jnp.array([T / (w * t), 0.0, 0.0]), (4, 1)), t))
    n_nodes = (nx + 1) * nz
    K = np.zeros((2 * n_nodes, 2 * n_nodes))
    node = lambda i, j: i * nz + j
    for i in range(nx):
        for j in range(nz - 1):
            nodes = [node(i, j), node(i, j + 1), node(i + 1, j), node(i + 1, j + 1)]
            dofs = np.ravel([[2 * a, 2 * a + 1] for a in nodes])
            K[np.ix_(dofs, dofs)] += Ke + Kg
    F = np.zeros(2 * n_nodes)
    mid = nx // 2
    F[[2 * node(mid, j) + 1 for j in range(nz)]] = P / nz
    fixed = np.ravel([[2 * node(i, j), 2 * node(i, j) + 1] for i in (0, nx) for j in range(nz)])
    free = np.setdiff1d(np.arange(2 * n_nodes), fixed)
    x = np.zeros(2 * n_nodes)
    x[free] = np.linalg.solve(K[np.ix_(free, free)], F[free])
    return np.mean(x[[2 * node(mid, j) + 1 for j in range(nz)]])


def _tensioned_beam(T, L=2.0, w=0.02, t=3e-4, E=2.5e9, P=1.0):
    """Euler–Bernoulli beam with tension, clamped at both ends, central load: EI y'''' − T y'' = 0 on
    the half span with y(0) = y'(0) = 0, y'(L/2) = 0 and shear P/2; y = A + Bx + C cosh Kx + D sinh Kx."""
    EI = E * t * w**3 / 12
    K = np.sqrt(T / EI)
    a = L / 2
    rows = np.array([
        [1, 0, 1, 0],
        [0, 1, 0, K],
        [0, 1, K * np.sinh(K * a), K * np.cosh(K * a)],
        [0, -T, EI * K**3 * np.sinh(K * a) - T * K * np.sinh(K * a), EI * K**3 * np.cosh(K * a) - T * K * np.cosh(K * a)],
    ])
    A, B, C, D = np.linalg.solve(rows, [0, 0, 0, -P / 2])
    return A + B * a + C * np.cosh(K * a) + D * np.sinh(K * a), K * L


@pytest.mark.parametrize("T", [50.0, 500.0])
def test_tension_stiffened_strip_is_a_tensioned_beam(T):
    """K L = 20 and 63 (tension-dominated, where the bilinear quads' bending error does not
    matter): the FE midspan deflection matches the tensioned beam to 3 %, and is far from the
    untensioned one."""
    fe = _strip_deflection(T)
    exact, KL = _tensioned_beam(T)
    assert KL >= 20
    assert abs(fe - exact) <= 0.03 * exact
    assert _strip_deflection(0.0) > 5 * fe


def test_tension_stiffening_needs_tension():
    """No pre-tension, no tension roller: K_σ = 0 and the model is unchanged (the source's scenes);
    with the tension roller's 200 N it changes the lateral response."""
    def model(name, ts):
        return jb.build_model(scene_with(lambda d: (d.setdefault("mesh", {}).update(n_eta=3),
                                                    d.setdefault("solver", {}).update(tension_stiffening=ts)), name))

    a, b = model("three-roller", False), model("three-roller", True)
    assert np.array_equal(np.asarray(a.K_diag), np.asarray(b.K_diag))
    c, d = model("three-roller-tension", False), model("three-roller-tension", True)
    dK = np.asarray(d.K_diag - c.K_diag)
    assert np.abs(dK).max() > 0 and np.allclose(dK, np.swapaxes(dK, 1, 2))
