"""Independent references: scikit-fem element matrices, dense solves, hand calculations."""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.assembly import dae_matrices
from jaxbelt.elements import free_belt_stiffness_1d
from jaxbelt.linalg import BorderedBlockCyclic
from helpers import span_strains


def test_bar_stiffness_matches_scikit_fem():
    skfem = pytest.importorskip("skfem")
    from skfem.models.poisson import laplace

    nodes = np.array([0.0, 0.003, 0.0071, 0.0102, 0.0155])
    m = skfem.MeshLine(nodes)
    basis = skfem.Basis(m, skfem.ElementLineP1())
    EA = 2.5e9 * 5e-6
    K_ref = (EA * laplace.assemble(basis)).toarray()
    # same elements as an open chain inside jaxbelt's cyclic format: a fifth (zero) element closes it
    ell = np.append(np.diff(nodes), 1.0)
    free = np.array([1.0, 1.0, 1.0, 1.0, 0.0])
    Kd, Kl, Ku = free_belt_stiffness_1d(jnp.asarray(ell), jnp.asarray(free), EA)
    K = BorderedBlockCyclic(Kd, Kl, Ku, jnp.zeros((5, 1, 0)), jnp.zeros((5, 0, 1)), jnp.zeros((0, 0))).to_dense()
    np.testing.assert_allclose(np.asarray(K), K_ref, rtol=1e-13, atol=1e-6)


def test_statics_translated_idle_roller_hand_calculation():
    """Idle roller moved by d away from the drive: strain d/D in both spans, no idle rotation."""
    sc = jb.load_scene("two-roller-1d-idle-translated")
    mesh = jb.build_mesh(sc)
    model = jb.build_model(sc, mesh)
    d, D = 1e-3, 0.275
    s0 = jb.initial_state(model)
    for eps in span_strains(model, mesh, s0.u):
        np.testing.assert_allclose(eps, d / D, rtol=1e-10)
    chi = np.asarray(s0.chi).reshape(2, 2)
    assert chi[1, 0] == pytest.approx(d)
    assert abs(chi[1, 1]) < 1e-14  # idle rotation α_z
    # contact-line values are the tangential components of the translation (R_r χ)
    on2 = np.asarray(mesh.node_roller) == 1
    np.testing.assert_allclose(np.asarray(s0.u)[on2, 0], np.asarray(model.R)[on2, 0, 2] * d, atol=1e-15)


def test_statics_tension_roller_force_balance():
    """Tension roller pulled with F: each span carries F/2 (no pre-tension, 180° wraps)."""
    sc = jb.load_scene("two-roller-1d-tension")
    mesh = jb.build_mesh(sc)
    model = jb.build_model(sc, mesh)
    s0 = jb.initial_state(model)
    EA = sc.belt.youngs_modulus * sc.belt.area
    for eps in span_strains(model, mesh, s0.u):
        np.testing.assert_allclose(EA * eps, 50.0, rtol=1e-10)
    d = float(np.asarray(s0.chi)[2])
    assert d == pytest.approx(50.0 / EA * 0.275, rel=1e-10)  # each span stretched by d


def test_pretension_statics():
    """A belt shorter than its path by δ carries the tension EA δ / L everywhere in the spans."""
    sc = jb.load_scene("two-roller-1d-pretension")
    mesh = jb.build_mesh(sc)
    model = jb.build_model(sc, mesh)
    s0 = jb.initial_state(model)
    eps0 = mesh.length / sc.belt.length - 1.0
    for eps in span_strains(model, mesh, s0.u):
        np.testing.assert_allclose(eps, 0.0, atol=1e-14)  # no extra strain: rollers are fixed
    # the idle roller's torque balance holds with the pre-tension on both sides
    K, _ = dae_matrices(model, model.m_e0)
    y_b, y_r = K.matvec(s0.u, s0.chi)
    from jaxbelt.assembly import static_rhs

    F_b, F_r = static_rhs(model)
    np.testing.assert_allclose(np.asarray(y_r), np.asarray(F_r), atol=1e-12)
    assert eps0 > 0


def test_quad_stiffness_matches_scikit_fem_plane_stress():
    skfem = pytest.importorskip("skfem")
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    from jaxbelt.elements import quad_stiffness

    E, nu, t, ell, w = 2.5e9, 0.34, 3e-4, 0.027, 0.0235
    K = np.asarray(quad_stiffness(ell, w, E, nu, t))
    mesh = skfem.MeshQuad(np.array([[0, ell, ell, 0], [0, 0, w, w]]), np.array([[0], [1], [2], [3]]))
    basis = skfem.Basis(mesh, skfem.ElementVector(skfem.ElementQuad1()), intorder=3)
    lam, mu = lame_parameters(E, nu)
    lam_plane_stress = 2 * lam * mu / (lam + 2 * mu)
    K_ref = (t * linear_elasticity(lam_plane_stress, mu).assemble(basis)).toarray()
    # skfem's nodes (0,0),(ℓ,0),(ℓ,w),(0,w) → jaxbelt's (i,j),(i,j+1),(i+1,j),(i+1,j+1)
    order = [0, 3, 1, 2]
    dofs = np.array([[basis.nodal_dofs[0, k], basis.nodal_dofs[1, k]] for k in order]).ravel()
    np.testing.assert_allclose(K, K_ref[np.ix_(dofs, dofs)], rtol=1e-12, atol=1e-12 * np.abs(K_ref).max())


def test_assembled_2d_stiffness_matches_scikit_fem_on_a_strip():
    """The free-belt blocks of a whole strip (3 element columns × 2 rows) against skfem."""
    skfem = pytest.importorskip("skfem")
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    from jaxbelt.elements import free_belt_stiffness_2d

    E, nu, t = 2.5e9, 0.34, 3e-4
    ell = np.array([0.02, 0.03, 0.025, 1.0])  # the 4th element column closes the loop and is not free
    free = np.array([1.0, 1.0, 1.0, 0.0])
    z = np.array([-0.02, 0.0, 0.02])
    Kd, Kl, Ku = free_belt_stiffness_2d(jnp.asarray(ell), jnp.asarray(np.diff(z)), jnp.asarray(free), E, nu, t)
    n, b = 4, 6
    K = BorderedBlockCyclic(Kd, Kl, Ku, jnp.zeros((n, b, 0)), jnp.zeros((n, 0, b)), jnp.zeros((0, 0))).to_dense()
    xs = np.concatenate([[0], np.cumsum(ell[:3])])
    mesh = skfem.MeshQuad.init_tensor(xs, z)
    basis = skfem.Basis(mesh, skfem.ElementVector(skfem.ElementQuad1()), intorder=3)
    lam, mu = lame_parameters(E, nu)
    K_ref = (t * linear_elasticity(2 * lam * mu / (lam + 2 * mu), mu).assemble(basis)).toarray()
    # map jaxbelt DOF (column i, row j, comp c) → skfem DOF of the node at (xs[i], z[j])
    perm = []
    for i in range(4):
        for j in range(3):
            k = int(np.argmin((mesh.p[0] - xs[i]) ** 2 + (mesh.p[1] - z[j]) ** 2))
            perm += [basis.nodal_dofs[0, k], basis.nodal_dofs[1, k]]
    np.testing.assert_allclose(np.asarray(K), K_ref[np.ix_(perm, perm)], rtol=1e-12, atol=1e-12 * np.abs(K_ref).max())
