"""The belt in 3D (:mod:`jaxbelt.plot.belt3d`) on a coarse 1D two-roller belt (50 mm rollers 275 mm
apart, 5 elements an arc, 6 a span; the idle roller 0.5 mm out along x), against hand geometry: the
roller centres rebuilt from the nodes, arc nodes on their roller, span nodes on the straight lines
y = ∓50 mm, tangents along the motion and normals outward; the drawn surface moved by ``u`` along
the tangent and by the idle roller's offset along the normal on its arc; the figure's colours,
rollers (moved by the exaggerated offset) and title; the refusals of bad arguments."""

import math

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import jaxbelt as jb  # noqa: E402
from helpers import scene_with  # noqa: E402
from jaxbelt.plot import belt_geometry_3d, belt_surface_3d, plot_belt_3d  # noqa: E402

R = 0.05  # m, both rollers


def _machine(d):
    d["mesh"].update(roller_elements=[5, 5], free_elements=[6, 6])
    d["belt"]["length_mm"] = 863.0
    d["roller"][1]["translation_mm"] = [0.5, 0.0, 0.0]


@pytest.fixture(scope="module")
def machine():
    scene = scene_with(_machine)
    mesh = jb.build_mesh(scene)
    return jb.build_model(scene, mesh), mesh


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def _arcs(model):
    nr = np.asarray(model.node_roller)
    return nr, np.asarray(model.node_theta)


def test_roller_centres_rebuilt_from_the_nodes_or_taken_from_the_mesh(machine):
    model, mesh = machine
    np.testing.assert_allclose(belt_geometry_3d(model)[3], [[0.0, 0.0], [0.275, 0.0]], atol=1e-15)
    np.testing.assert_array_equal(belt_geometry_3d(model, mesh)[3], mesh.path.centers)


def test_node_positions_tangents_and_normals(machine):
    model, _ = machine
    P, tang, normal, centres = belt_geometry_3d(model)
    nr, th = _arcs(model)
    assert P.shape == (22, 1, 3) and tang.shape == normal.shape == (22, 3)
    assert np.all(P[..., 2] == 0.0) and np.all(tang[:, 2] == 0.0)  # the 1D belt's one line at z = 0
    radial = np.stack([np.cos(th), np.sin(th)], 1)
    on = nr >= 0
    np.testing.assert_allclose(P[on, 0, :2], centres[nr[on]] + R * radial[on], atol=1e-15)
    np.testing.assert_allclose(normal[on, :2], radial[on], atol=1e-15)  # outward on the arcs
    # the drive arc runs down the left side (counter-clockwise), the idle one up the right side
    np.testing.assert_allclose(tang[on, :2], np.stack([-np.sin(th), np.cos(th)], 1)[on], atol=1e-15)
    lower, upper = np.arange(6, 11), np.arange(17, 22)  # the span nodes between the contact lines
    np.testing.assert_allclose(P[lower, 0, :2], np.stack([np.arange(1, 6) * 0.275 / 6, np.full(5, -R)], 1),
                               atol=1e-15)
    np.testing.assert_allclose(P[upper, 0, :2], np.stack([0.275 - np.arange(1, 6) * 0.275 / 6, np.full(5, R)], 1),
                               atol=1e-15)
    np.testing.assert_allclose(tang[lower], np.tile([1.0, 0.0, 0.0], (5, 1)), atol=1e-15)
    np.testing.assert_allclose(tang[upper], np.tile([-1.0, 0.0, 0.0], (5, 1)), atol=1e-15)
    np.testing.assert_allclose(normal[lower], np.tile([0.0, -1.0, 0.0], (5, 1)), atol=1e-15)  # outward: down
    np.testing.assert_allclose(normal[upper], np.tile([0.0, 1.0, 0.0], (5, 1)), atol=1e-15)


def test_the_surface_follows_the_idle_rollers_offset_along_the_normal(machine):
    model, _ = machine
    surf = belt_surface_3d(model, np.zeros((22, 1)))
    nr, th = _arcs(model)
    # the idle roller 0.5 mm along x: its surface moves by 0.5 mm × cos θ along the normal; the drive's not
    expected_w = np.where(nr == 1, 5e-4 * np.cos(th), 0.0)
    np.testing.assert_allclose(surf["w"][:, 0], expected_w, atol=1e-18)
    assert np.max(surf["w"]) == pytest.approx(5e-4 * math.cos(math.pi / 10), rel=1e-12)
    P, _, normal, _ = belt_geometry_3d(model)
    np.testing.assert_allclose(surf["points"], P + expected_w[:, None, None] * normal[:, None, :], atol=1e-18)
    np.testing.assert_array_equal(surf["reference"], P)
    np.testing.assert_array_equal(surf["v"], 0.0)  # no lateral field in 1D


def test_the_surface_moves_along_the_tangent_by_u_exaggerated(machine):
    model, _ = machine
    u = np.linspace(-1e-4, 2e-4, 22)[:, None]
    chi = np.zeros(4)  # the rollers where they are drawn: no normal motion
    surf = belt_surface_3d(model, u, chi=chi, exaggerate=30.0)
    P, tang, _, _ = belt_geometry_3d(model)
    np.testing.assert_allclose(surf["u"][:, 0], u[:, 0])
    np.testing.assert_allclose(surf["points"], P + 30.0 * u[:, :, None] * tang[:, None, :], atol=1e-15)
    spun = belt_surface_3d(model, u, chi=np.array([0.0, 0.0, 0.0, 0.7]), exaggerate=30.0)  # rotation az: not drawn
    np.testing.assert_allclose(spun["points"], surf["points"], atol=1e-15)
    np.testing.assert_array_equal(belt_surface_3d(model, u, exaggerate=0.0)["points"], P)


def test_the_figure_colours_each_element_by_its_mean_magnitude(machine):
    model, mesh = machine
    u = np.linspace(-1e-4, 2e-4, 22)[:, None]
    ax = plot_belt_3d(model, u, mesh=mesh)
    coll = ax.collections[0]
    mag = np.abs(np.append(u[:, 0], u[0, 0])) * 1e3  # mm, the loop closed
    np.testing.assert_allclose(coll.get_array(), 0.5 * (mag[:-1] + mag[1:]), rtol=1e-12)
    assert len(coll.get_array()) == 22  # one segment per element
    assert ax.get_title() == "belt coloured by magnitude [mm]; displacements to scale"
    assert ax.figure.axes[1].get_ylabel() == "|u| [mm]"
    assert [t.get_text() for t in ax.texts] == ["drive", "idle"]
    assert len(ax.collections) == 3  # the belt and the two roller surfaces


def test_the_rollers_are_drawn_moved_by_their_exaggerated_offset(machine):
    model, mesh = machine
    ax = plot_belt_3d(model, np.zeros((22, 1)), mesh=mesh, color_by="u", exaggerate=100.0, title="t = 1 s")
    assert ax.get_title() == "t = 1 s\nbelt coloured by u [mm]; displacements × 100"
    rims = [line for line in ax.lines if len(line.get_data_3d()[0]) == 41]  # two rims a roller
    assert len(rims) == 4
    centre_x = [0.5 * (np.max(line.get_data_3d()[0]) + np.min(line.get_data_3d()[0])) for line in rims]
    np.testing.assert_allclose(centre_x, [0.0, 0.0, 325.0, 325.0], atol=1e-9)  # 275 mm + 100 × 0.5 mm
    half_widths = [line.get_data_3d()[1][0] for line in rims]  # the rims at z = ∓30 mm
    np.testing.assert_allclose(half_widths, [-30.0, 30.0, -30.0, 30.0], atol=1e-9)


@pytest.mark.parametrize("kwargs,message", [
    (dict(color_by="w"), r"^color_by = 'w': expected 'magnitude', 'u' or 'v'$"),
    (dict(color_by="v"), r"^color_by = 'v' asked of a 1D model, which has no lateral displacement$"),
    (dict(exaggerate=float("nan")), r"^exaggerate = nan: must be a finite number ≥ 0$"),
    (dict(exaggerate=-0.5), r"^exaggerate = -0.5: must be a finite number ≥ 0$"),
])
def test_bad_arguments_are_refused(machine, kwargs, message):
    model, _ = machine
    with pytest.raises(ValueError, match=message):
        plot_belt_3d(model, np.zeros((22, 1)), **kwargs)


def test_a_field_of_another_shape_is_refused(machine):
    model, _ = machine
    with pytest.raises(ValueError) as e:
        plot_belt_3d(model, np.zeros(22))
    assert str(e.value) == "u: shape (22,), expected (n_xi, b) = (22, 1) (one time: state.u or traj.u[k])"
    assert plt.get_fignums() == []  # refused before a figure is made
