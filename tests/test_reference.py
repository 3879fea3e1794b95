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
    model = jb.compile_scene(sc, mesh)
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
    model = jb.compile_scene(sc, mesh)
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
    model = jb.compile_scene(sc, mesh)
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
