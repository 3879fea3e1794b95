"""Misalignment parameters (:mod:`jaxbelt.misalignment`) against hand-worked index tables: which
components of a three-roller 2D machine (a drive, an idle roller, a tension roller loaded along y)
can vary and why the others cannot, the selection syntax and its error messages, the design-unit
map ``χ = base + 10⁻³ θ`` and its derivative, and the 1D model (``dx`` only) built from a coarse
``two-roller-1d`` scene."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxbelt import misalignment as mis
from jaxbelt.rollers import DOFS_2D
from helpers import load, scene_with


@dataclasses.dataclass(frozen=True)
class _Machine:
    """The fields of a model the parameter maps read."""
    kind: str
    roller_names: tuple
    dofs: tuple
    dynamic: jax.Array
    chi_static: jax.Array

    @property
    def n_rollers(self):
        return len(self.roller_names)

    def replace(self, **kw):
        return dataclasses.replace(self, **kw)


def _machine_2d():
    dynamic = np.zeros((3, 6), bool)
    dynamic[1:, DOFS_2D.index("az")] = True  # idle and tension rollers turn freely
    dynamic[2, DOFS_2D.index("dy")] = True  # the tension roller's load
    chi = jnp.asarray(np.random.default_rng(0).standard_normal(18) * 1e-3)
    return _Machine("2d", ("drive", "idle", "tension"), DOFS_2D, jnp.asarray(dynamic.reshape(-1)), chi)


@pytest.fixture(scope="module")
def model_1d():
    return load(scene_with(lambda d: d["mesh"].update(roller_elements=[5, 5], free_elements=[6, 6])))[0]


def test_every_free_component_of_a_2d_machine_and_why_the_others_cannot_vary():
    space = mis.parameter_space(_machine_2d())
    free = [(j, c) for j in range(3) for c in ("dx", "dy", "dz", "ax", "ay") if (j, c) != (2, "dy")]
    assert list(space.entries) == free and space.size == 14
    assert space.chi_index == tuple(6 * j + DOFS_2D.index(c) for j, c in free)
    structural = dict(space.structural)
    assert set(structural) == {(0, "az"), (1, "az"), (2, "az"), (2, "dy")}
    assert "no static effect" in structural[(0, "az")] and "load sets it" in structural[(2, "dy")]
    assert space.labels()[:3] == ["drive:dx", "drive:dy", "drive:dz"]
    assert space.units()[:5] == ["mm", "mm", "mm", "mrad", "mrad"]


@pytest.mark.parametrize("select,entries", [
    ("idle:rotation", [(1, "ax"), (1, "ay")]),
    ("tension", [(2, "dx"), (2, "dz"), (2, "ax"), (2, "ay")]),
    (" idle:ay , drive:dx, idle:ay,idle:translation ", [(0, "dx"), (1, "dx"), (1, "dy"), (1, "dz"), (1, "ay")]),
    (["tension:translation", "drive:ax"], [(0, "ax"), (2, "dx"), (2, "dz")])])
def test_selection_picks_sorted_unique_components(select, entries):
    assert list(mis.parameter_space(_machine_2d(), select).entries) == entries


@pytest.mark.parametrize("select,message", [
    ("belt", r"components = 'belt': no roller named 'belt' \(rollers: drive, idle, tension\)"),
    ("idle:bz", r"components = 'idle:bz': unknown component 'bz' \(translation, rotation or one of dx, dy"),
    ("idle:az", r"components = 'idle:az': rotation about the roller's own axis has no static effect"),
    ("tension:dy", r"components = 'tension:dy': force/torque-loaded: the load sets it"),
    (" , ", r"components = ' , ': names no component")])
def test_selection_errors_name_the_item_and_the_reason(select, message):
    with pytest.raises(ValueError, match=message):
        mis.parameter_space(_machine_2d(), select)


def test_one_d_model_varies_only_dx(model_1d):
    space = mis.parameter_space(model_1d)
    assert list(space.entries) == [(0, "dx"), (1, "dx")] and space.labels() == ["drive:dx", "idle:dx"]
    with pytest.raises(ValueError, match="components = 'idle:ax': not modelled by the 1d model"):
        mis.parameter_space(model_1d, "idle:ax")


def test_per_roller_and_index_place_values_by_hand():
    space = mis.parameter_space(_machine_2d(), "idle:ay,tension:dx")
    out = space.per_roller([2.5, -1.0], fill=np.nan)
    assert out["idle"]["rotation"][1] == 2.5 and out["tension"]["translation"][0] == -1.0
    assert np.isnan(out["drive"]["translation"]).all() and np.isnan(out["idle"]["rotation"][0])
    assert space.index("tension", "dx") == 1 and space.index("idle", "ay") == 0


def test_apply_adds_theta_in_milli_units_and_its_derivative_is_one_thousandth():
    m = _machine_2d()
    space = mis.parameter_space(m, "drive:dz,idle:ax")
    theta = jnp.asarray([2.0, -3.0])  # mm, mrad
    chi = np.asarray(mis.apply(m, space, theta).chi_static)
    want = np.asarray(m.chi_static).copy()
    want[2] += 2e-3
    want[6 + 3] -= 3e-3
    np.testing.assert_allclose(chi, want, rtol=0, atol=1e-18)
    base = jnp.zeros(18)
    np.testing.assert_allclose(np.asarray(mis.apply(m, space, theta, base).chi_static)[[2, 9]], [2e-3, -3e-3])
    J = jax.jacobian(lambda th: mis.apply(m, space, th).chi_static)(theta)
    expected = np.zeros((18, 2))
    expected[2, 0] = expected[9, 1] = 1e-3
    np.testing.assert_array_equal(np.asarray(J), expected)


def test_dof_directions_and_aligned():
    m = _machine_2d()
    D = np.asarray(mis.dof_directions(m, [4, 11], scale=2.0, rows=3))
    expected = np.zeros((3, 18))
    expected[0, 4] = expected[1, 11] = 2.0
    np.testing.assert_array_equal(D, expected)
    assert np.all(np.asarray(mis.aligned(m).chi_static) == 0) and np.any(np.asarray(m.chi_static) != 0)


def test_with_misalignment_sets_translations_and_rotations_per_roller():
    m = _machine_2d()
    t = np.arange(9.0).reshape(3, 3) * 1e-3
    a = -np.arange(9.0).reshape(3, 3) * 1e-4
    chi = np.asarray(mis.with_misalignment(m, t, a).chi_static).reshape(3, 6)
    np.testing.assert_array_equal(chi[:, :3], t)
    np.testing.assert_array_equal(chi[:, 3:5], a[:, :2])
    np.testing.assert_array_equal(chi[:, 5], np.asarray(m.chi_static).reshape(3, 6)[:, 5])  # α_z kept
    chi_x = np.asarray(mis.with_misalignment(m, [1e-3, 0.0, -2e-3]).chi_static).reshape(3, 6)
    np.testing.assert_array_equal(chi_x[:, :3], [[1e-3, 0, 0], [0, 0, 0], [-2e-3, 0, 0]])


def test_with_misalignment_on_the_1d_model_refuses_what_it_cannot_carry(model_1d):
    chi = np.asarray(mis.with_misalignment(model_1d, [0.0, 1e-3]).chi_static).reshape(2, 2)
    assert chi[:, 0].tolist() == [0.0, 1e-3]
    with pytest.raises(ValueError, match="the 1d model has no translation along y"):
        mis.with_misalignment(model_1d, [[0.0, 1e-3, 0.0], [0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match="the 1d model has no rotation about x"):
        mis.with_misalignment(model_1d, rotation=[[1e-3, 0.0, 0.0], [0.0, 0.0, 0.0]])
    with pytest.raises(ValueError, match=r"translation: shape \(3,\), expected \(2,\) .* or \(2, 3\)"):
        mis.with_misalignment(model_1d, [0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"rotation: shape \(2,\), expected \(2, 3\)"):
        mis.with_misalignment(model_1d, rotation=[0.0, 0.0])
