"""The non-locking plane-stress element (QM6, incompatible modes) against an independent numpy
reference, the patch test, rigid-body modes, exact pure bending, and the lateral bending of a
clamped strip against Timoshenko beam theory (where the bilinear quad locks); the scene key.

scikit-fem has no incompatible-modes element, so the QM6 matrix is cross-checked against the
12 × 12 Wilson Q6 matrix written here independently (natural coordinates s, t ∈ [−1, 1],
counter-clockwise nodes, DOFs blocked ``u₁..u₄, v₁..v₄, a₁..a₄``, 3 × 3 Gauss instead of 2 × 2),
condensed with numpy; its bilinear part ``K_cc`` is the matrix that ``tests/unit/test_reference.py``
checks against scikit-fem's ``ElementQuad1``. On rectangles Q6 and Taylor's QM6 coincide.
"""

import sys

import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt.elements import free_belt_stiffness_2d, quad_qm6_stiffness, quad_stiffness
from jaxbelt.linalg import BorderedBlockCyclic
from jaxbelt.scene import SceneError
from helpers import REPO, scene_with

sys.path.insert(0, str(REPO / "benchmarks"))
from bending_locking import beam_deflection, strip_deflection  # noqa: E402

E, NU, T = 2.5e9, 0.34, 3e-4
_CCW = [0, 3, 1, 2]  # jaxbelt node k = counter-clockwise node _CCW[k]: (0,0), (0,w), (ℓ,0), (ℓ,w)


def q6_reference(ell, w, E=E, nu=NU, t=T):
    """Wilson's Q6 on the rectangle [0, ℓ] × [0, w], condensed, in jaxbelt's DOF order (numpy)."""
    sn, tn = np.array([-1.0, 1.0, 1.0, -1.0]), np.array([-1.0, -1.0, 1.0, 1.0])
    D = E / (1 - nu**2) * np.array([[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]])
    g, wg = np.polynomial.legendre.leggauss(3)
    K = np.zeros((12, 12))
    for s, ws in zip(g, wg):
        for r, wr in zip(g, wg):
            dNs = np.concatenate([sn * (1 + r * tn) / 4, [-2 * s, 0.0]]) * 2 / ell  # ∂/∂x of N₁..N₄, 1−s², 1−t²
            dNt = np.concatenate([tn * (1 + s * sn) / 4, [0.0, -2 * r]]) * 2 / w  # ∂/∂z
            B = np.zeros((3, 12))
            B[0, [0, 1, 2, 3, 8, 9]] = dNs  # u = Σ Nᵢ uᵢ + a₁ (1−s²) + a₂ (1−t²), v with a₃, a₄
            B[1, [4, 5, 6, 7, 10, 11]] = dNt
            B[2, [0, 1, 2, 3, 8, 9]] = dNt
            B[2, [4, 5, 6, 7, 10, 11]] = dNs
            K += ws * wr * t * B.T @ D @ B * (ell * w / 4)
    Kc = K[:8, :8] - K[:8, 8:] @ np.linalg.solve(K[8:, 8:], K[8:, :8])
    perm = np.ravel([[_CCW[k], 4 + _CCW[k]] for k in range(4)])
    return Kc[np.ix_(perm, perm)]


@pytest.mark.parametrize("ell,w", [(0.027, 0.0235), (0.1, 0.01), (0.004, 0.08)])
def test_qm6_equals_independent_q6_reference(ell, w):
    K = np.asarray(quad_qm6_stiffness(ell, w, E, NU, T))
    ref = q6_reference(ell, w)
    np.testing.assert_allclose(K, ref, rtol=1e-11, atol=1e-11 * np.abs(ref).max())
    np.testing.assert_array_equal(K, K.T)


def _assemble(xs, zs, element):
    """Dense stiffness of the rectangle grid ``xs × zs``; node (i, j) has DOFs 2 (i n_z + j) + (0, 1)."""
    nz = len(zs)
    K = np.zeros((2 * len(xs) * nz, 2 * len(xs) * nz))
    for i in range(len(xs) - 1):
        for j in range(nz - 1):
            Ke = element(xs[i + 1] - xs[i], zs[j + 1] - zs[j])
            nodes = [i * nz + j, i * nz + j + 1, (i + 1) * nz + j, (i + 1) * nz + j + 1]
            dofs = np.ravel([[2 * a, 2 * a + 1] for a in nodes])
            K[np.ix_(dofs, dofs)] += Ke
    return K


@pytest.mark.parametrize("field", [(1e-3, 0, 0, 0), (0, 1e-3, 0, 0), (0, 0, 1e-3, 0), (2e-4, -3e-4, 5e-4, -1e-4)])
def test_qm6_patch_test(field):
    """Unequal rectangles, linear displacement on the boundary: the interior nodes take the linear
    field exactly (constant strain reproduced), and ``K u_lin`` has no interior residual."""
    xs, zs = np.array([0.0, 0.013, 0.041, 0.052]), np.array([0.0, 0.007, 0.02, 0.031])
    K = _assemble(xs, zs, lambda l, h: np.asarray(quad_qm6_stiffness(l, h, E, NU, T)))
    X, Z = np.meshgrid(xs, zs, indexing="ij")
    exx, ezz, gxz, rot = field
    u_lin = np.stack([3e-4 + exx * X + (gxz / 2 - rot) * Z, -2e-4 + ezz * Z + (gxz / 2 + rot) * X], -1).ravel()
    inner = np.zeros(X.shape, bool)
    inner[1:-1, 1:-1] = True
    i = np.flatnonzero(np.repeat(inner.ravel(), 2))
    b = np.setdiff1d(np.arange(len(u_lin)), i)
    u_i = np.linalg.solve(K[np.ix_(i, i)], -K[np.ix_(i, b)] @ u_lin[b])
    np.testing.assert_allclose(u_i, u_lin[i], rtol=0, atol=1e-12 * np.abs(u_lin).max())
    np.testing.assert_allclose((K @ u_lin)[i], 0.0, atol=1e-9 * np.abs(K @ u_lin).max())


@pytest.mark.parametrize("ell,w", [(0.027, 0.0235), (0.1, 0.01), (0.004, 0.08)])
def test_qm6_rigid_body_modes(ell, w):
    K = np.asarray(quad_qm6_stiffness(ell, w, E, NU, T))
    lam = np.linalg.eigvalsh(K)
    assert np.sum(np.abs(lam) < 1e-10 * lam.max()) == 3
    assert lam[3] > 1e-6 * lam.max()
    x, z = np.array([0, 0, ell, ell]), np.array([0, w, 0, w])
    modes = [np.tile([1.0, 0.0], 4), np.tile([0.0, 1.0], 4), np.stack([-z, x], 1).ravel()]
    for m in modes:
        assert np.abs(K @ m).max() < 1e-10 * lam.max() * np.abs(m).max()


@pytest.mark.parametrize("aspect", [1.0, 4.0, 10.0])
def test_qm6_pure_bending_is_exact(aspect):
    """Nodal values of the exact pure-bending field ``u = κ x z``, ``v = −κ (x² + ν z²)/2`` (about the
    centre): QM6's strain energy is the exact ``E t κ² ℓ h³ / 24``; the bilinear quad's is
    ``(1 + (1 − ν) a²/2) / (1 − ν²)`` times larger for aspect ratio a = ℓ/h: parasitic shear (a²) and
    the missing ``z²`` in v (Poisson), 1.50 at a = 1 and 38 at a = 10: it locks."""
    h = 0.01
    ell, kappa = aspect * h, 0.3
    x, z = np.array([0, 0, ell, ell]) - ell / 2, np.array([0, h, 0, h]) - h / 2
    u = np.stack([kappa * x * z, -kappa * (x**2 + NU * z**2) / 2], 1).ravel()
    exact = E * T * kappa**2 * ell * h**3 / 24
    U = lambda K: 0.5 * u @ np.asarray(K) @ u
    assert U(quad_qm6_stiffness(ell, h, E, NU, T)) == pytest.approx(exact, rel=1e-12)
    assert U(quad_stiffness(ell, h, E, NU, T)) == pytest.approx((1 + (1 - NU) * aspect**2 / 2) / (1 - NU**2) * exact,
                                                                 rel=1e-12)


@pytest.mark.parametrize("case", ["clamped-clamped", "cantilever"])
def test_strip_bending_matches_timoshenko_beam(case):
    """Clamped strip, L/w = 100, two elements across (n_eta = 3), ℓ/h = 1 … 10: QM6 deflects within
    2 % of the Timoshenko beam (κ = 5/6); the bilinear quad is too stiff by 11 % at ℓ/h = 1 and by
    a factor > 8 at ℓ/h = 10 (in-plane bending locking, ``benchmarks/bending_locking.py``)."""
    beam = beam_deflection(case)
    for aspect in (1, 2, 3, 5, 7, 10):
        ratio = strip_deflection("qm6", 3, aspect, case)[0] / beam
        assert abs(ratio - 1) < 0.02, (aspect, ratio)
    assert strip_deflection("q4", 3, 1, case)[0] / beam < 0.9
    assert strip_deflection("q4", 3, 10, case)[0] / beam < 0.125


def test_assembled_qm6_strip_equals_reference():
    """The vmapped free-belt blocks with ``element="qm6"`` (3 element columns × 2 unequal rows; a 4th,
    non-free column closes the loop) against the numpy Q6 reference assembled by hand."""
    ell = np.array([0.02, 0.05, 0.006, 1.0])
    z = np.array([-0.02, 0.0, 0.013])
    Kd, Kl, Ku = free_belt_stiffness_2d(jnp.asarray(ell), jnp.asarray(np.diff(z)), jnp.asarray([1.0, 1, 1, 0]),
                                        E, NU, T, element="qm6")
    n, b = 4, 6
    K = BorderedBlockCyclic(Kd, Kl, Ku, jnp.zeros((n, b, 0)), jnp.zeros((n, 0, b)), jnp.zeros((0, 0))).to_dense()
    ref = _assemble(np.concatenate([[0], np.cumsum(ell[:3])]), z, q6_reference)
    np.testing.assert_allclose(np.asarray(K), ref, rtol=1e-11, atol=1e-11 * np.abs(ref).max())
    with pytest.raises(ValueError, match="element = 'q8'"):
        free_belt_stiffness_2d(jnp.asarray(ell), jnp.asarray(np.diff(z)), jnp.ones(4), E, NU, T, element="q8")


def test_scene_element_key():
    import jaxbelt as jb

    def sc(**mesh):
        return scene_with(lambda d: (d["mesh"].update(n_eta=3, **mesh), d.update(solver={"tension_stiffening": False})),
                          "three-roller")

    from jaxbelt.elements import DEFAULT_ELEMENT, QUAD_ELEMENTS
    from jaxbelt.scene import _ELEMENTS, MeshSpec

    assert sc().mesh.element == MeshSpec().element == DEFAULT_ELEMENT == _ELEMENTS[0] == "qm6"
    assert set(_ELEMENTS) == set(QUAD_ELEMENTS)
    q4, qm6 = jb.build_model(sc(element="q4")), jb.build_model(sc())
    free = jnp.asarray(jb.build_mesh(sc()).elem_free, float)
    for model, element in ((q4, "q4"), (qm6, "qm6")):
        Kd = free_belt_stiffness_2d(model.ell, jnp.diff(model.z0), free, 2.5e9, 0.34, 3e-4, element=element)[0]
        np.testing.assert_array_equal(np.asarray(model.K_diag), np.asarray(Kd))
    assert not np.allclose(np.asarray(q4.K_diag), np.asarray(qm6.K_diag))
    with pytest.raises(SceneError, match="mesh.element = 'q8'.*qm6, q4"):
        sc(element="q8")
    with pytest.raises(SceneError, match="mesh.element = 'q4'.*2D only"):
        scene_with(lambda d: d.setdefault("mesh", {}).update(element="q4"))
