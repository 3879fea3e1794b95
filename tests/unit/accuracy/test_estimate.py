"""The pieces of the discretisation-error estimate: observed order, Richardson's limit, grid
refinement of a scene and its admissibility."""

import numpy as np
import pytest
from helpers import scene_with

from jaxbelt.accuracy import ORDER_RANGE, admissible, observed_order, refine, richardson_limit, scene_grid


@pytest.mark.parametrize("p", [1.0, 2.0, 1.37])
def test_order_and_limit_are_exact_for_a_power_law(p):
    rng = np.random.default_rng(0)
    q_inf, c = rng.normal(size=(7, 3)), rng.normal(size=(7, 3))
    h = [0.4, 0.2, 0.1]
    q = [q_inf + c * hh**p for hh in h]
    got, clamped = observed_order(h, q)
    assert not clamped and got == pytest.approx(p, rel=1e-9)
    np.testing.assert_allclose(richardson_limit(h, q, got), q_inf, atol=1e-12)


def test_order_with_unequal_ratios():
    h = [1.0 / 8, 1.0 / 17, 1.0 / 34]  # element rows 8, 17, 34 across
    q = [3.0 + 2.0 * hh**2 for hh in h]
    p, clamped = observed_order(h, [np.array([v]) for v in q])
    assert p == pytest.approx(2.0, rel=1e-9) and not clamped


def test_order_outside_the_range_is_clamped_and_round_off_gives_none():
    h = [0.4, 0.2, 0.1]
    q = [np.array([1.0 + 1e-3 * hh**8]) for hh in h]  # order 8: beyond the range
    p, clamped = observed_order(h, q)
    assert p == ORDER_RANGE[1] and clamped
    flat = [np.array([1.0, 2.0])] * 3
    assert observed_order(h, flat) == (None, False)
    np.testing.assert_array_equal(richardson_limit(h, flat, None), flat[2])


def test_refine_scales_every_direction():
    scene = scene_with(lambda d: d.update(model={"kind": "2d"}, mesh={"n_eta": 3, "roller_elements": [6, 6],
                                                                       "free_elements": [8, 8]}))
    g = scene_grid(scene)
    assert (g.n_xi, g.n_eta) == (28, 3)
    fine = refine(scene, n_xi=2.0, n_eta=2.0, dt=4.0)
    gf = scene_grid(fine)
    assert (gf.n_xi, gf.n_eta, gf.dt) == (56, 5, pytest.approx(g.dt / 4))
    assert fine.time.t_end == scene.time.t_end
    assert scene_grid(refine(scene, n_eta=0.5)).n_eta == 2


def test_admissible_checks_cfl_arcs_and_sampling():
    scene = scene_with(lambda d: None)  # two-roller-1d: 40 elements an arc, CFL 0.64
    assert admissible(scene)
    assert not admissible(refine(scene, dt=0.5))  # CFL 1.28
    assert admissible(refine(scene, n_xi=0.25, dt=0.5))  # 10 an arc, CFL 0.64
    assert not admissible(refine(scene, n_xi=0.1))  # 4 elements an arc
    assert not admissible(scene.replace(time=scene.time.__class__(dt=0.003, t_end=0.01)))  # 3.33 steps


def test_the_text_output_says_when_an_estimate_is_doubtful(capsys):
    """An observed order held at a bound, and an estimate larger than the signal, are said in the
    text output too (not only flagged in the JSON); a sound estimate gets no warning."""
    from jaxbelt.cli._accuracy import print_accuracy

    def summary(order, clamped, lateral_um, v_max_um):
        return dict(tracer_u_max_abs_um=1e3, tracer_v_max_abs_um=v_max_um, discretisation_error_um=dict(
            longitudinal=2.0, lateral=lateral_um, dominant="dt", orders={"dt": order, "n_xi": 1.0},
            directions={"dt": dict(order=order, order_clamped=clamped), "n_xi": dict(order=1.0, order_clamped=False)},
            cost_runs=3.0))

    print_accuracy(summary(4.0, True, 81.0, 60.0))
    out = capsys.readouterr().out
    assert "the observed order in dt sits at a bound of its range (4)" in out
    assert "the lateral error estimate (81 µm) exceeds the lateral signal itself (max |tracer| 60 µm)" in out
    print_accuracy(summary(1.0, False, 5.0, 60.0))
    assert "warning" not in capsys.readouterr().out
