"""Belt walk: the Timoshenko-beam loop reference (jaxbelt.lateral_theory) and the 2D model against it."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from helpers import load, simulate_optimised
from jaxbelt import lateral_theory as th

E, NU, T_B, R, SPAN = 2.5e9, 0.34, 0.3e-3, 0.08, 1.0
L_LOOP = 2 * SPAN + 2 * np.pi * R


def two_roller(w_mm=50.0, eps0=5e-3, n_xi=200, n_eta=5, dt=0.01, t_end=16.0):
    d = {"model": {"kind": "2d", "name": "two-roller-2d"},
         "belt": {"width_mm": w_mm, "thickness_mm": T_B * 1e3, "youngs_modulus_pa": E, "poisson_ratio": NU,
                  "density_kg_m3": 1420.0, "length_mm": L_LOOP * 1e3 / (1 + eps0)},
         "roller": [{"name": f"roller {k + 1}", "center_mm": [1000.0 * k, 0.0], "radius_mm": R * 1e3,
                     "width_mm": 450.0, "mass_kg": 3.0,
                     **({"role": "drive", "speed_m_s": 1.0} if k == 0 else {"role": "idle"})} for k in range(2)],
         "mesh": {"n_eta": n_eta, "n_xi": n_xi}, "time": {"dt_s": dt, "t_end_s": t_end},
         "solver": {"lateral_transport": True, "linear_solver": "reuse"}}
    return jb.scene_from_dict(d)


def geometry():
    return th.scene_geometry(two_roller())[0]


def rot(roller, axis, alpha=1e-3, p=2):
    a = np.zeros((p, 3))
    a[roller, axis] = alpha
    return a


# --- the reference on its own ------------------------------------------------------------------


def test_reference_string_limit_is_normal_entry_with_loop_closure():
    g = geometry()
    EI, _ = th.belt_section(0.05, T_B, E, NU)
    c = th.beam_walk_rate(g, rot(1, 1), tension=1e13, EI=EI)
    assert c == pytest.approx(-1e-3 * SPAN / L_LOOP, rel=1e-4)


def test_reference_beam_limit_is_a_third_of_the_string_rate():
    g = geometry()
    EI, kGA = th.belt_section(0.05, T_B, E, NU)
    c_eb = th.beam_walk_rate(g, rot(1, 1), tension=0.0, EI=EI)
    assert c_eb == pytest.approx(-1e-3 * SPAN / L_LOOP / 3, rel=1e-9)
    # the tensioned formula tends to the untensioned one
    assert th.beam_walk_rate(g, rot(1, 1), tension=1e-4 * EI, EI=EI) == pytest.approx(c_eb, rel=1e-4)  # K L = 0.01


def test_reference_twist_walks_by_the_per_pass_shift():
    g = geometry()
    EI, kGA = th.belt_section(0.05, T_B, E, NU)
    for T in (0.0, 50.0, 5000.0):
        assert th.beam_walk_rate(g, rot(1, 0), T, EI, kGA) == pytest.approx(2 * R * 1e-3 / L_LOOP, rel=1e-9)


def test_reference_is_linear_and_timoshenko_tends_to_euler_bernoulli():
    g = geometry()
    EI, kGA = th.belt_section(0.2, T_B, E, NU)
    a, b = rot(1, 1, 1e-3), rot(0, 0, 2e-3)
    c = lambda r, s=kGA: th.beam_walk_rate(g, r, 200.0, EI, s)  # noqa: E731
    assert c(a + b) == pytest.approx(c(a) + c(b), rel=1e-10)
    assert c(a, 1e6 * kGA) == pytest.approx(c(a, np.inf), rel=1e-5)
    assert abs(c(a) / c(a, np.inf) - 1) > 1e-3  # shear matters for a 200 mm belt on a 1 m span


@pytest.mark.parametrize("T", [0.0, 187.5])
def test_reference_span_shape_solves_the_beam_equations(T):
    """The returned steady shape satisfies both equilibrium equations (finite differences) and the
    zero-moment and normal-entry conditions at the entry line."""
    g = geometry()
    EI, kGA = th.belt_section(0.3, T_B, E, NU)
    c, shape = th.beam_walk_rate(g, rot(1, 1), T, EI, kGA, return_shape=True)
    x, h = np.linspace(0.1, 0.9, 9), 1e-3
    y = lambda x: np.array([shape(0, xi)[0] for xi in np.atleast_1d(x)])  # noqa: E731
    phi = lambda x: np.array([shape(0, xi)[1] for xi in np.atleast_1d(x)])  # noqa: E731
    yp = (y(x + h) - y(x - h)) / (2 * h)
    phipp = (phi(x + h) - 2 * phi(x) + phi(x - h)) / h**2
    Q = kGA * (yp - phi(x)) + T * yp
    assert np.ptp(Q) <= 1e-5 * np.max(np.abs(kGA * (yp - phi(x)))) + 1e-12
    assert np.allclose(EI * phipp + kGA * (yp - phi(x)), 0.0, atol=1e-4 * np.max(np.abs(EI * phipp)) + 1e-9)
    L = g.span_length[0]
    phip_L = (phi(L) - phi(L - h))[0] / h
    assert abs(phip_L) < 1e-3 * np.max(np.abs((phi(x + h) - phi(x - h)) / (2 * h)))
    yp_L = ((y(L) - y(L - h)) / h)[0]
    sigma_in = th.roller_slope(rot(1, 1)[1], g.span_direction[0])
    assert c == pytest.approx(1.0 * (sigma_in - yp_L), rel=1e-3)


def test_steering_split_of_a_tilted_roller():
    """A tilt about x of a roller whose spans run along ±x is pure twist; on the three-roller
    scene roller 2's tilt is part skew for its leaving span."""
    g = geometry()
    s = th.steering_split(g, rot(1, 0))[1]
    assert s["skew_in_rad"] == pytest.approx(0.0, abs=1e-15) and s["skew_out_rad"] == pytest.approx(0.0, abs=1e-15)
    assert abs(s["per_pass_shift_m"]) == pytest.approx(2 * R * 1e-3)
    g3, _ = th.scene_geometry(jb.load_scene("three-roller"))
    s3 = th.steering_split(g3, rot(1, 0, p=3))[1]
    assert abs(s3["skew_out_rad"]) > 0.5e-3 and abs(s3["skew_in_rad"]) < 0.05e-3


# --- the 2D model against it -------------------------------------------------------------------


@pytest.fixture(scope="module")
def two_roller_loaded():
    return load(two_roller())


@pytest.fixture(scope="module")
def two_roller_model(two_roller_loaded):
    return two_roller_loaded[0]


def _walk(tr):
    t, v = np.asarray(tr.t), np.asarray(tr.tracer_v).mean(axis=1)
    n = len(t)
    return float(np.polyfit(t[n // 2:], v[n // 2:], 1)[0])


def _run(loaded, rotation):
    """1600 steps (16 s) with ``rotation``: one program for the module, compiled optimised (long
    runs: ``helpers.simulate_optimised``)."""
    model, opts = loaded
    return simulate_optimised(jb.with_misalignment(model, rotation=jnp.asarray(rotation)), opts)


@pytest.fixture(scope="module")
def skew_run(two_roller_loaded):
    """Roller 2 skewed by 1 mrad: the trajectory of two tests below."""
    return _run(two_roller_loaded, rot(1, 1))


def test_skew_walk_equals_the_timoshenko_loop(skew_run):
    """K L = 4.9 (50 mm belt, ε₀ = 5e-3): the walk on a skewed roller is neither the string's nor
    the beam's; the 2D model gives the reference's within 2 % on this mesh (0.1 % at n_ξ = 400,
    benchmarks/lateral_theory.py)."""
    sc = two_roller()
    c = _walk(skew_run)
    ref = th.scene_walk_rate(sc, rot(1, 1))
    assert c == pytest.approx(ref, rel=0.02)
    assert abs(c / (-1e-3 * SPAN / L_LOOP)) < 0.7  # far from the string limit at this K L


def test_twist_walk_equals_the_per_pass_shift(two_roller_loaded):
    c = _walk(_run(two_roller_loaded, rot(1, 0)))
    assert c == pytest.approx(2 * R * 1e-3 / L_LOOP, rel=0.01)


@jax.jit  # one program for both cases, not op by op
def _entry_line_correction(m, s):
    """The normal-entry correction of the static state for a uniform shift ``s`` (m)."""
    from jaxbelt.transport import entry_line_correction, upwind_weights

    st = jb.initial_state(m)
    a, fwd = upwind_weights(jnp.full((m.n_xi, m.n_eta), s), m.ell)
    return entry_line_correction(m, jnp.repeat(a, 2, axis=1), jnp.repeat(fwd, 2, axis=1), st.chi)


@pytest.mark.parametrize("axis", [0, 1])
def test_entry_line_correction_is_the_roller_skew_at_the_contact_line(two_roller_model, axis):
    """The normal-entry term moves an entry node's v by ``s σ``: ``σ`` the lateral slope of the
    roller's circumferential lines at the contact line (reference formula ``e_z · (α × t)``),
    for a skew (σ = ∓α) and a twist (σ = 0 on spans along x); u is untouched."""
    s = 0.01
    m = jb.with_misalignment(two_roller_model, rotation=jnp.asarray(rot(1, axis)))
    corr = np.asarray(_entry_line_correction(m, s))
    g = geometry()
    node_roller = np.asarray(m.node_roller)
    for j in (0, 1):
        entry = np.flatnonzero((node_roller == j) & (np.roll(node_roller, 1) != j))
        assert len(entry) == 1
        sigma = th.roller_slope(rot(1, axis)[j], g.span_direction[(j - 1) % 2])
        assert np.allclose(corr[entry[0], 1::2] / s, sigma, rtol=1e-12, atol=1e-15)  # the exact skew
    assert np.count_nonzero(np.abs(corr[:, 1::2]) > 1e-15) <= 2 * m.n_eta  # entry nodes only


def test_steady_span_shape_equals_the_reference(skew_run):
    """Beyond the rate: in steady walk the lateral shape of both spans (tracers on the centre line,
    the walk's offset removed) is the reference's Timoshenko span shape within 3 % of its range."""
    sc = two_roller()
    mesh = jb.build_mesh(sc)
    v = np.asarray(skew_run.tracer_v[-1])
    _, shape = th.beam_walk_rate(th.scene_geometry(sc)[0], rot(1, 1), E * 5e-3 * 0.05 * T_B,
                            *th.belt_section(0.05, T_B, E, NU), return_shape=True)
    _, d_model, d_ref = th.span_tracer_shapes(mesh, v, shape)
    assert len(d_model) == 10
    assert np.ptp(d_ref) > 1e-4  # a shape worth comparing (α = 1 mrad: ~0.5 mm)
    assert np.max(np.abs(d_model - d_ref)) < 0.03 * np.ptp(d_ref)
