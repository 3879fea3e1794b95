"""The reduced models' figures (:mod:`jaxbelt.plot.reduction`) on hand-made data: the singular values
drawn normalised by the first (zeros left out) with the kept modes marked, the DMD eigenvalues in
the complex plane with the unit circle and a colour scale (logarithmic over more than two decades),
the RMSE over time with the tolerance and an estimate, and the report figure's panels and title."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.colors import LogNorm  # noqa: E402

from jaxbelt.plot import plot_dmd_eigenvalues, plot_reduction, plot_rmse_over_time, plot_singular_values  # noqa: E402


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def test_singular_values_normalised_with_the_kept_modes_marked():
    s = np.array([-4.0, 2.0, 1.0, 0.0, 0.5])  # the magnitude counts; a zero is left out of the log plot
    ax = plot_singular_values(s, n_modes=2)
    line, kept = ax.get_lines()[0], ax.get_lines()[2]
    np.testing.assert_array_equal(line.get_xdata(), [1, 2, 3, 4, 5])
    np.testing.assert_array_equal(line.get_ydata(), [1.0, 0.5, 0.25, np.nan, 0.125])
    np.testing.assert_array_equal(kept.get_ydata(), [1.0, 0.5])
    assert ax.get_lines()[1].get_xdata() == [2.5, 2.5]  # between the kept and the dropped modes
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["2 modes kept"]
    assert ax.get_yscale() == "log" and ax.get_ylabel() == "σᵢ / σ₀"


@pytest.mark.parametrize("n_modes", [None, 0, 6])
def test_no_mark_without_a_mode_count_within_the_values(n_modes):
    ax = plot_singular_values(np.array([3.0, 2.0, 1.0, 0.5, 0.1]), n_modes=n_modes)
    assert len(ax.get_lines()) == 1 and ax.get_legend() is None


def test_singular_values_all_zero_are_drawn_as_nothing():
    ax = plot_singular_values(np.zeros(3))
    assert np.all(np.isnan(ax.get_lines()[0].get_ydata()))


def test_eigenvalues_in_the_plane_with_the_unit_circle():
    lam = np.array([0.9 + 0.1j, 0.5 - 0.5j, 1.0 + 0j])
    ax = plot_dmd_eigenvalues(lam)
    circle, points = ax.get_lines()
    np.testing.assert_allclose(np.hypot(circle.get_xdata(), circle.get_ydata()), 1.0, rtol=1e-12)
    np.testing.assert_array_equal(points.get_xdata(), lam.real)
    np.testing.assert_array_equal(points.get_ydata(), lam.imag)
    assert points.get_label() == "3 eigenvalues" and len(ax.figure.axes) == 1  # no colour bar


def test_weighted_eigenvalues_on_a_log_scale_over_more_than_two_decades():
    lam = np.array([0.9 + 0.1j, 0.5 - 0.5j, 0.2 + 0j, 0.8 + 0.3j])
    w = np.array([1e-4, 1.0, 0.0, 1e-2])  # one zero weight: drawn at the smallest positive one
    ax = plot_dmd_eigenvalues(lam, weights=w)
    sc = ax.collections[0]
    assert isinstance(sc.norm, LogNorm) and (sc.norm.vmin, sc.norm.vmax) == (1e-4, 1.0)
    order = [2, 0, 3, 1]  # weakest first, the strongest drawn on top
    np.testing.assert_array_equal(sc.get_offsets(), np.stack([lam.real[order], lam.imag[order]], 1))
    np.testing.assert_array_equal(sc.get_array(), [1e-4, 1e-4, 1e-2, 1.0])
    assert len(ax.figure.axes) == 2 and ax.figure.axes[1].get_ylabel() == "scaled mode norm ‖φᵢ bᵢ‖"


def test_weighted_eigenvalues_on_a_linear_scale_within_two_decades():
    lam = np.array([0.9 + 0.1j, 0.5 - 0.5j, 0.2 + 0j])
    ax = plot_dmd_eigenvalues(lam, weights=[-2.0, 1.0, 50.0])  # magnitudes
    sc = ax.collections[0]
    assert not isinstance(sc.norm, LogNorm) and (sc.norm.vmin, sc.norm.vmax) == (1.0, 50.0)
    np.testing.assert_array_equal(sc.get_array(), [1.0, 2.0, 50.0])


def test_rmse_over_time_with_the_tolerance_and_an_estimate():
    t = np.array([0.1, 0.2, 0.3, 0.4])
    ax = plot_rmse_over_time(t, [0.0, 1.0, 2.0, 3.0], tol_um=5.0, estimate_um=[0.5, 4.0], estimate_t=[0.2, 0.4],
                             estimate_label="indicator")
    rmse, tol, est = ax.get_lines()
    np.testing.assert_array_equal(rmse.get_ydata(), [np.nan, 1.0, 2.0, 3.0])
    assert list(tol.get_ydata()) == [5.0, 5.0] and tol.get_label() == "tolerance 5 µm"
    np.testing.assert_array_equal(est.get_xdata(), [0.2, 0.4])
    np.testing.assert_array_equal(est.get_ydata(), [0.5, 4.0])
    assert est.get_label() == "indicator" and ax.get_yscale() == "log"
    ax2 = plot_rmse_over_time(t, [1.0, 1.0, 1.0, 1.0], tol_um=None, estimate_um=[1, 2, 3, 4])
    assert len(ax2.get_lines()) == 2  # no tolerance line
    np.testing.assert_array_equal(ax2.get_lines()[1].get_xdata(), t)  # the estimate at the run's times by default


def test_panels_draw_on_the_axes_given():
    fig, ax = plt.subplots()
    assert plot_singular_values([1.0, 0.1], ax=ax) is ax
    assert plot_rmse_over_time([0.1, 0.2], [1.0, 2.0], ax=ax) is ax
    assert len(fig.axes) == 1


@pytest.mark.parametrize("singular,eigs,panels", [(True, True, 3), (True, False, 2), (False, False, 1)])
def test_report_figure_panels_and_title(singular, eigs, panels):
    t = np.array([0.1, 0.2, 0.3])
    fig = plot_reduction(dict(scene="belt", method="dmd", modes=2, rmse_um=0.01234), t, [0.1, 0.2, 0.3],
                         singular_values=[1.0, 0.1, 0.01] if singular else None,
                         eigs=np.array([0.9, 0.5j]) if eigs else None)
    main = [ax for ax in fig.axes if ax.get_label() != "<colorbar>"]
    assert len(main) == panels
    assert [ax.get_title() for ax in main][-1] == "error over time"
    if singular:
        assert main[0].get_title() == "singular values of the snapshots"
        assert main[0].get_legend().get_texts()[0].get_text() == "2 modes kept"
    assert fig.get_suptitle() == "belt: dmd, 2 modes, RMSE 0.0123 µm"


def test_report_title_without_an_error_figure(tmp_path):
    fig = plot_reduction(dict(scene="belt", method="pod", modes=4, rmse_um=None), [0.1], [1.0])
    assert fig.get_suptitle() == "belt: pod, 4 modes"
    path = tmp_path / "r.png"
    assert plot_reduction({}, [0.1], [1.0], path=path) == path and path.stat().st_size > 0
