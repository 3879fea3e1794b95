"""The tolerance box of a linear response (jaxbelt.design.linear_box): analytic, scipy, worst corners."""

import numpy as np
import pytest

from jaxbelt.design import linear_box


def test_box_of_an_exactly_linear_model_is_analytic():
    """One response row r = a·θ: max Σ w log h s.t. Σ |a_k| h_k ≤ L gives h_k = w_k L / (Σw |a_k|)."""
    a = np.array([2.0, -0.5, 8.0, 1.0])
    w = np.array([1.0, 2.0, 1.0, 0.5])
    lin = linear_box.LinearResponse(np.zeros(1), a[None, :], "max")
    h = linear_box.optimise_box(lin, 20.0, w, h_max=100.0)
    np.testing.assert_allclose(h, w * 20.0 / (w.sum() * np.abs(a)), rtol=2e-3)
    # with the cap h ≤ 5 active on component 1, the others share what is left
    h = linear_box.optimise_box(lin, 20.0, w, h_max=5.0)
    rest = np.array([0, 2, 3])
    np.testing.assert_allclose(h[rest], w[rest] * 17.5 / (w[rest].sum() * np.abs(a[rest])), rtol=2e-3)
    assert np.isclose(linear_box.worst_case(lin, h), 20.0, rtol=1e-9)


def test_box_with_several_rows_and_rms_matches_scipy():
    from scipy.optimize import minimize

    rng = np.random.default_rng(3)
    J = rng.normal(size=(6, 3))
    r0 = 0.5 * rng.normal(size=6)
    for kind in ("max", "rms"):
        lin = linear_box.LinearResponse(r0, J, kind)
        h = linear_box.optimise_box(lin, 10.0)
        cons = {"type": "ineq", "fun": lambda y: 10.0 - linear_box.worst_case(lin, np.exp(y))}
        ref = minimize(lambda y: -np.sum(y), np.log(h * 0.5), constraints=[cons], method="SLSQP",
                       bounds=[(None, np.log(linear_box.H_MAX))] * 3, options={"ftol": 1e-12, "maxiter": 500})
        assert np.sum(np.log(h)) >= -ref.fun - 2e-3
        assert linear_box.worst_case(lin, h) <= 10.0 + 1e-9


def test_box_with_thousands_of_rows_satisfies_the_optimality_conditions():
    """A max-type box over 3000 response rows: the Karush-Kuhn-Tucker conditions hold at the result
    (w/h a non-negative combination of the active rows, by NNLS), and another start of the
    Lagrangian gives the same box."""
    from scipy.optimize import nnls

    rng = np.random.default_rng(7)
    J = rng.normal(size=(3000, 6)) * np.array([1.0, 3.0, 0.3, 10.0, 1.0, 0.05])
    r0 = rng.normal(size=3000)
    lin = linear_box.LinearResponse(r0, J, "max")
    w = np.array([1.0, 1.0, 2.0, 1.0, 0.5, 1.0])
    h = linear_box.optimise_box(lin, 20.0, w)
    other = linear_box.optimise_box(lin, 20.0, w, outer=3, inner=20)
    np.testing.assert_allclose(other, h, rtol=1e-6)
    g = np.abs(r0) + np.abs(J) @ h
    assert np.isclose(g.max(), 20.0, rtol=1e-9)
    active, free = np.flatnonzero(g > 20.0 * (1 - 1e-6)), h < linear_box.H_MAX * (1 - 1e-9)
    lam, residual = nnls(np.abs(J)[active][:, free].T, (w / h)[free])
    assert residual <= 1e-6 * np.linalg.norm((w / h)[free])


def test_rss_stackup_of_one_row():
    lin = linear_box.LinearResponse(np.zeros(1), np.array([[3.0, 4.0]]), "max")
    assert np.isclose(linear_box.rss_stackup(lin, [1.0, 1.0]).three_sigma_um, 15.0)


@pytest.mark.parametrize("kind", ["max", "rms"])
@pytest.mark.parametrize("offset", [0.0, 0.7])
def test_worst_case_equals_enumerating_every_corner(kind, offset):
    import itertools

    rng = np.random.default_rng(1)
    J = rng.normal(size=(7, 5))
    lin = linear_box.LinearResponse(offset * rng.normal(size=7), J, kind)
    h = rng.uniform(0.1, 1.0, size=5)
    corners = np.array(list(itertools.product((-1.0, 1.0), repeat=5)))
    brute = max(lin.metric(c * h) for c in corners)
    signs, vals = linear_box.worst_corners(lin, h, 3)
    assert np.isclose(linear_box.worst_case(lin, h), brute, rtol=1e-12)
    assert np.isclose(lin.metric(signs[0] * h), brute, rtol=1e-12) and np.all(np.diff(vals) <= 0)

