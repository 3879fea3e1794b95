"""Belt path geometry and the grid."""

import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.geometry import belt_path, tangent_span


def test_two_roller_path_length_and_wraps():
    p = belt_path([(0, 0), (0.275, 0)], [0.05, 0.05], [False, False])
    assert p.length == pytest.approx(2 * 0.275 + 2 * np.pi * 0.05, rel=1e-14)
    assert [s.kind for s in p.segments] == ["roller", "free", "roller", "free"]
    assert p.segments[0].wrap == pytest.approx(np.pi)
    np.testing.assert_allclose(p.segments[0].start, [0, 0.05], atol=1e-15)  # incoming contact at the top
    np.testing.assert_allclose(p.segments[1].start, [0, -0.05], atol=1e-15)


@pytest.mark.parametrize("rho_a,rho_b", [(0.05, 0.03), (0.05, -0.03), (-0.02, 0.04)])
def test_tangent_touches_both_circles(rho_a, rho_b):
    ca, cb = np.array([0.0, 0.0]), np.array([0.3, 0.1])
    pa, pb, e, L = tangent_span(ca, rho_a, cb, rho_b)
    assert np.linalg.norm(pa - ca) == pytest.approx(abs(rho_a))
    assert np.linalg.norm(pb - cb) == pytest.approx(abs(rho_b))
    assert (pa - ca) @ e == pytest.approx(0, abs=1e-14)  # perpendicular to the radius
    assert (pb - cb) @ e == pytest.approx(0, abs=1e-14)
    assert np.linalg.norm(pb - pa) == pytest.approx(L)


def test_three_roller_total_turning_and_length():
    sc = jb.load_scene("three-roller-1d")
    mesh = jb.build_mesh(sc)
    turning = sum(s.sense * s.wrap for s in mesh.path.segments if s.kind == "roller")
    assert turning == pytest.approx(2 * np.pi)
    assert mesh.length == pytest.approx(sum(s.length for s in mesh.path.segments))


def test_grid_of_two_roller_1d():
    mesh = jb.build_mesh(jb.load_scene("two-roller-1d"))
    assert mesh.n_xi == 220
    assert (mesh.node_roller >= 0).sum() == 82  # 41 columns on each arc, contact lines included
    assert mesh.ell.sum() == pytest.approx(mesh.length)
    np.testing.assert_allclose(np.diff(mesh.x), mesh.ell[:-1], rtol=1e-12)
    assert len(mesh.tracer_x) == 20  # 5 per segment


def test_n_xi_distribution_is_exact():
    from helpers import scene_with

    def m(d):
        d["mesh"] = {"n_xi": 230}
    mesh = jb.build_mesh(scene_with(m))
    assert mesh.n_xi == 230
