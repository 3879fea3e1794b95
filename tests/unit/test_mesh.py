"""The fixed grid of :mod:`jaxbelt.mesh` on the two-roller machine, against its hand-computed
geometry (two rollers of radius r = 50 mm, 275 mm apart: two half-wraps of π r and two free spans of
275 mm): column positions, element lengths, segment starts, roller and free flags for a given
element count; the counts the mesh options choose; tracer placement and location; the CFL advice;
and the refusals of tracers outside the belt."""

import math

import numpy as np
import pytest

from jaxbelt.mesh import CFL_ADVICE_FACTOR, MIN_ARC_ELEMENTS, build_mesh, cfl_advice
from jaxbelt.scene_values import SceneError
from helpers import scene_with

R, SPAN = 0.05, 0.275
ARC = math.pi * R


def _mesh(mesh=None, output=None, width_mm=None, kind="1d"):
    def mutate(d):
        d["model"]["kind"] = kind
        if mesh is not None:
            d["mesh"] = mesh
        if output is not None:
            d["output"] = output
        if width_mm is not None:
            d["belt"]["width_mm"] = width_mm
    return build_mesh(scene_with(mutate))


def test_columns_and_elements_of_a_given_count_follow_the_path():
    m = _mesh({"roller_elements": [5, 5], "free_elements": [6, 6]})
    assert m.n_xi == 22 and m.n_eta == 1 and m.roller_elements == (5, 5) and m.free_elements == (6, 6)
    ell = np.r_[[ARC / 5] * 5, [SPAN / 6] * 6, [ARC / 5] * 5, [SPAN / 6] * 6]
    np.testing.assert_allclose(m.ell, ell, rtol=1e-12)
    np.testing.assert_allclose(m.x, np.r_[0.0, np.cumsum(ell)[:-1]], rtol=1e-12, atol=1e-15)
    assert m.length == pytest.approx(2 * ARC + 2 * SPAN, rel=1e-12)
    assert m.segment_starts.tolist() == [0, 6, 11, 17]  # an arc holds n + 1 columns, a span n - 1
    assert m.node_roller.tolist() == [0] * 6 + [-1] * 5 + [1] * 6 + [-1] * 5
    assert m.elem_free.tolist() == [False] * 5 + [True] * 6 + [False] * 5 + [True] * 6
    assert np.all(m.node_theta[m.node_roller < 0] == 0.0)
    for j in (0, 1):  # a half wrap: the angle turns by π in equal steps
        th = np.unwrap(m.node_theta[m.node_roller == j])
        np.testing.assert_allclose(np.abs(np.diff(th)), math.pi / 5, rtol=1e-12)


def test_default_mesh_puts_ten_elements_on_the_shortest_arc():
    m = _mesh({})
    h = ARC / 10
    assert m.roller_elements == (10, 10) and m.free_elements == (round(SPAN / h),) * 2


def test_element_length_sets_the_counts_by_rounding():
    m = _mesh({"element_length_mm": 12.0})
    assert m.roller_elements == (round(ARC / 0.012),) * 2 and m.free_elements == (round(SPAN / 0.012),) * 2


@pytest.mark.parametrize("n_xi", [40, 41, 57, 100])
def test_a_column_count_is_met_exactly(n_xi):
    m = _mesh({"n_xi": n_xi})
    assert m.n_xi == sum(m.roller_elements) + sum(m.free_elements) == n_xi
    assert np.ptp(m.ell) < 0.25 * m.ell.mean()  # nearly uniform: the remainder spread, not dumped on one segment


def test_rows_span_the_belt_width():
    m = _mesh({"n_eta": 3, "roller_elements": [5, 5], "free_elements": [6, 6]}, width_mm=40.0, kind="2d")
    np.testing.assert_allclose(m.z, [-0.02, 0.0, 0.02], atol=1e-15)


def test_too_few_elements_on_an_arc_names_the_minimum():
    with pytest.raises(SceneError, match=rf"mesh.n_xi: \d element\(s\) on the arc of 'drive' .*at least "
                                         rf"{MIN_ARC_ELEMENTS}"):
        _mesh({"n_xi": 12})


def test_tracers_sit_at_the_segment_quarters_and_are_located_on_their_elements():
    m = _mesh({"roller_elements": [5, 5], "free_elements": [6, 6]},
              output={"tracers_per_segment": 2, "tracers_mm": [[100.0, 10.0], [0.0, 0.0]]})
    starts = np.cumsum([0.0, ARC, SPAN, ARC])
    lengths = [ARC, SPAN, ARC, SPAN]
    expected = [s + f * L for s, L in zip(starts, lengths) for f in (0.25, 0.75)] + [0.1, 0.0]
    np.testing.assert_allclose(m.tracer_x, expected, rtol=1e-12)
    np.testing.assert_allclose(m.tracer_z, [0.0] * 8 + [0.01, 0.0])
    col, xi = m.tracer_location()
    assert col.dtype == np.int32 and np.all((xi >= 0) & (xi < 1))
    np.testing.assert_allclose(m.x[col] + xi * m.ell[col], expected, rtol=1e-12, atol=1e-15)
    assert col[-1] == 0 and xi[-1] == 0.0  # a tracer on the first contact line
    assert col[0] == int(0.25 * ARC // (ARC / 5))  # on the first arc, by hand


@pytest.mark.parametrize("tracer,why", [([900.0, 0.0], r"x = 900 mm outside the belt \[0, 864\.159\)"),
                                        ([-1.0, 0.0], "x = -1 mm outside the belt"),
                                        ([10.0, 25.5], "z = 25.5 mm outside the belt width")])
def test_tracers_off_the_belt_are_refused(tracer, why):
    with pytest.raises(SceneError, match=rf"output\.tracers_mm: {why}"):
        _mesh({"roller_elements": [5, 5], "free_elements": [6, 6]}, output={"tracers_mm": [tracer]})


def test_a_scene_that_records_nothing_is_refused():
    with pytest.raises(SceneError, match="the scene records nothing"):
        _mesh({"roller_elements": [5, 5], "free_elements": [6, 6]}, output={"tracers_per_segment": 0})


def test_cfl_advice_is_a_fraction_of_the_bound():
    text = cfl_advice(0.004, 0.5, "--dt")
    assert text.startswith(f"use --dt <= {CFL_ADVICE_FACTOR * 0.008:.4g} s (the bound is 0.008 s;")
    assert CFL_ADVICE_FACTOR < 1
