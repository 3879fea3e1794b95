"""The model pytree (:mod:`jaxbelt.model`) of a coarse ``two-roller-1d`` belt (5 elements per arc, 6
per span) against hand counts: 22 node columns, 2 × 2 roller DOFs, 26 unknowns, of which the 12
arc-column no-slip rows and the 3 prescribed roller DOFs (the drive's ``d_x`` and ``α_z``, the idle
roller's ``d_x``) are algebraic; the partition read from the arrays equals the stored one; array
fields are leaves (``vmap`` reaches ``chi_static``), structure is static."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from helpers import load, scene_with


@pytest.fixture(scope="module")
def model():
    return load(scene_with(lambda d: d["mesh"].update(roller_elements=[5, 5], free_elements=[6, 6])))[0]


def test_sizes_are_the_hand_counts(model):
    assert (model.n_xi, model.block, model.n_eta, model.n_rollers, model.n_roller_dofs) == (22, 1, 1, 2, 4)
    assert model.n_unknowns == 22 + 4 and model.n_tracers == 4 * 5
    assert model.coupling_band == 0 and model.replace(kind="2d").coupling_band == 3
    assert model.roller_names == ("drive", "idle") and model.dofs == ("dx", "az")


def test_partition_puts_no_slip_rows_and_prescribed_roller_dofs_on_the_algebraic_side(model):
    dynamic, algebraic = model.partition
    arc_columns = [*range(0, 6), *range(11, 17)]  # the arc of roller 1, then of roller 2 (contact lines included)
    roller = 22  # the flat index of the first roller DOF
    assert algebraic == tuple(arc_columns) + (roller + 0, roller + 1, roller + 2)
    assert dynamic == tuple([*range(6, 11), *range(17, 22), roller + 3])  # free nodes, the idle roller's α_z
    assert model.n_algebraic == 15


def test_partition_from_the_arrays_equals_the_stored_one(model):
    assert model.algebraic_index is not None
    assert model.replace(algebraic_index=None).partition == model.partition


def test_replace_returns_a_changed_copy_and_keeps_the_tree_structure(model):
    chi = jnp.asarray([1e-3, 0.0, -2e-3, 0.0])
    moved = model.replace(chi_static=chi)
    assert np.all(np.asarray(model.chi_static) == 0.0) and np.asarray(moved.chi_static).tolist() == chi.tolist()
    assert jax.tree.structure(moved) == jax.tree.structure(model)
    assert jax.tree.structure(model.replace(roller_names=("a", "b"))) != jax.tree.structure(model)


def test_vmap_reaches_the_misalignment_leaf(model):
    chis = jnp.stack([jnp.zeros(4), jnp.asarray([0.0, 0.0, 1e-3, 0.0])])
    out = jax.vmap(lambda c: jnp.sum(model.replace(chi_static=c).chi_static * model.M_roller))(chis)
    np.testing.assert_allclose(np.asarray(out), [0.0, 1e-3 * float(model.M_roller[2])], rtol=1e-15)
    assert float(model.M_roller[2]) == pytest.approx(0.5)  # the idle roller's mass, kg (scene file)
