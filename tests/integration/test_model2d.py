"""The 2D plane-stress model (MODEL.md §4): counts, solves, invariants, symmetry, linearity.

The runs share the coarse grid (three lines across) and a few run lengths that are whole numbers
of the scan's checkpoint chunks (9, 36, 156), so that they share compiled programs (with each other
and with test_vmap.py, test_validation.py's 2D statics, integrators/test_reuse.py, rom/test_snapshots.py)."""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from jaxbelt.assembly import dae_matrices, roller_R
from jaxbelt.linalg import bordered_solve, dense_solve, join
from helpers import load, scene_with


@functools.cache
def small(name="three-roller", n_eta=3):
    """``(model, run options)`` of a built-in scene with ``n_eta`` lines across (built once)."""
    def m(d):
        d.setdefault("mesh", {})["n_eta"] = n_eta
    return load(scene_with(m, name))


def simulate(m, n_steps, solver=None, name="three-roller"):
    """``jb.simulate`` of ``m`` at the time step of the scene it was built from."""
    opts = small(name)[1]
    return jb.simulate(m, solver or opts.solver, n_steps=n_steps, dt=opts.dt)


def with_variant(model, rollers):
    """Misalignments as {roller index: dict(translation=(x, y, z) m, rotation=(x, y) rad)}."""
    t = np.zeros((model.n_rollers, 3))
    r = np.zeros((model.n_rollers, 3))
    for j, v in rollers.items():
        t[j] = v.get("translation", (0, 0, 0))
        r[j, :2] = v.get("rotation", (0, 0))
    return jb.with_misalignment(model, translation=jnp.asarray(t), rotation=jnp.asarray(r))


@pytest.mark.parametrize("scene,n_eta,expected", [("three-roller", 18, 3762), ("three-roller", 4, 850),
                                                  ("four-roller-external", 18, 3768), ("three-roller-tension", 5, None)])
def test_unknown_counts(scene, n_eta, expected):
    m, _ = small(scene, n_eta=n_eta)
    assert m.n_unknowns == 2 * m.n_xi * m.n_eta + 6 * m.n_rollers
    if expected is not None:
        assert m.n_unknowns == expected


def test_default_scene_count_via_info(capsys):
    import json

    from jaxbelt.cli import main

    assert main(["info", "three-roller", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["n_unknowns"] == 3762 and info["n_xi"] == 104 and info["n_eta"] == 18


@pytest.mark.reference
def test_structured_solve_equals_dense_2d():
    base, opts = small(n_eta=4)
    m = with_variant(base, {0: dict(translation=(0, 2e-3, 1e-3)), 1: dict(rotation=(4e-4, 2e-4))})
    s0 = jb.initial_state(m)
    R = roller_R(m, s0.u)
    K, M = dae_matrices(m, s0.m_e, R)
    A = M + K.scale(opts.dt**2)
    rng = np.random.default_rng(0)
    rb, rr = jnp.asarray(rng.normal(size=(m.n_xi, m.block))), jnp.asarray(rng.normal(size=m.n_roller_dofs))
    structured, dense = jax.jit(bordered_solve), jax.jit(dense_solve)  # one program each, not op by op
    for mat in (A, K):
        x1, x2 = join(*structured(mat, rb, rr)), join(*dense(mat, rb, rr))
        assert float(jnp.linalg.norm(x1 - x2) / jnp.linalg.norm(x2)) < 1e-10


def test_mass_conserved_500_steps_and_idle_speeds():
    m = with_variant(small()[0], {0: dict(translation=(1e-3, 2e-3, 0)), 2: dict(rotation=(3e-4, 0))})
    _, tr = simulate(m, 500)
    mass = np.asarray(tr.belt_mass)
    assert np.max(np.abs(mass - mass[0])) / mass[0] < 1e-13
    w = np.asarray(tr.roller_velocity)[-1, :, 5]
    radii = np.array([0.08, 0.06, 0.10])
    np.testing.assert_allclose(np.abs(w) * radii, 1.0, rtol=1e-3)


def test_aligned_stretched_belt_is_symmetric():
    """No lateral misalignment, belt stretched by moving roller 2 outwards: Poisson contraction
    only, v = 0 on the centre line and v(-z) = -v(z), u(-z) = u(z)."""
    m = with_variant(small()[0], {1: dict(translation=(2e-3, 0, 0))})
    s, tr = simulate(m, 36)
    u, v = np.asarray(s.u[:, 0::2]), np.asarray(s.u[:, 1::2])
    assert np.max(np.abs(v)) > 1e-7  # the contraction is there (the test is not vacuous)
    np.testing.assert_allclose(v[:, 1], 0.0, atol=1e-15 + 1e-9 * np.max(np.abs(v)))
    np.testing.assert_allclose(v, -v[:, ::-1], atol=1e-9 * np.max(np.abs(v)))
    np.testing.assert_allclose(u, u[:, ::-1], atol=1e-9 * np.max(np.abs(u)))
    assert np.max(np.abs(np.asarray(tr.tracer_v))) < 1e-9 * np.max(np.abs(v))  # tracers on the centre line


def test_mirrored_lateral_misalignment_mirrors_the_field():
    base = small()[0]
    a = with_variant(base, {0: dict(translation=(0, 0, 1e-3)), 1: dict(rotation=(4e-4, -2e-4))})
    b = with_variant(base, {0: dict(translation=(0, 0, -1e-3)), 1: dict(rotation=(-4e-4, 2e-4))})
    sa, _ = simulate(a, 36)
    sb, _ = simulate(b, 36)
    ua, va = np.asarray(sa.u[:, 0::2]), np.asarray(sa.u[:, 1::2])
    ub, vb = np.asarray(sb.u[:, 0::2]), np.asarray(sb.u[:, 1::2])
    assert np.max(np.abs(va)) > 1e-5
    np.testing.assert_allclose(vb, -va[:, ::-1], atol=1e-9 * np.max(np.abs(va)))
    np.testing.assert_allclose(ub, ua[:, ::-1], atol=1e-9 * max(np.max(np.abs(ua)), 1e-9))


def test_doubling_a_small_misalignment_doubles_the_response():
    base = small()[0]
    c1 = {0: dict(translation=(0, 1e-4, 1e-4)), 1: dict(rotation=(5e-5, 0)), 2: dict(rotation=(0, 4e-5))}
    c2 = {k: {kk: tuple(2 * x for x in vv) for kk, vv in v.items()} for k, v in c1.items()}
    zero = simulate(base, 36)[1]
    r1 = simulate(with_variant(base, c1), 36)[1]
    r2 = simulate(with_variant(base, c2), 36)[1]
    for f in ("tracer_u", "tracer_v"):
        d1 = np.asarray(getattr(r1, f) - getattr(zero, f))
        d2 = np.asarray(getattr(r2, f) - getattr(zero, f))
        assert np.linalg.norm(d2 - 2 * d1) < 0.01 * np.linalg.norm(2 * d1)


@pytest.mark.parametrize("name", ["naive", "eliminated"])
def test_integrators_agree_2d(name):
    """The eliminated and the naive integrator give the direct one's run. The naive one (a dense
    3N = 1926 solve a step) is slow here; integrators/test_integrators.py checks it in 1D."""
    m = with_variant(small()[0], {0: dict(translation=(0, 1e-3, 5e-4)), 1: dict(rotation=(3e-4, 1e-4))})
    ref = simulate(m, 9, jb.make_solver("direct"))[1]
    scale = float(jnp.max(jnp.abs(ref.tracer_u)))
    tr = simulate(m, 9, jb.make_solver(name))[1]
    assert float(jnp.max(jnp.abs(tr.tracer_u - ref.tracer_u))) < 1e-9 * scale
    assert float(jnp.max(jnp.abs(tr.tracer_v - ref.tracer_v))) < 1e-9 * scale


def test_tension_roller_moves_and_is_balanced():
    m, _ = small("three-roller-tension")
    s, tr = simulate(m, 156, name="three-roller-tension")
    dx = np.asarray(tr.roller_state)[-1, 1, 0]
    assert dx > 0  # pulled outwards by the 200 N
    w = np.asarray(tr.roller_velocity)[-1, :, 5]
    np.testing.assert_allclose(np.abs(w) * np.array([0.08, 0.06, 0.10]), 1.0, rtol=2e-3)


def test_exact_static_rotation_matches_linear_for_small_angles():
    from jaxbelt.rollers import exact_static_displacement

    m, _ = small()
    chi = jnp.zeros((3, 6)).at[1, 3].set(1e-6).at[1, 4].set(-2e-6).at[0, 1].set(1e-6)
    g = exact_static_displacement(chi, m.node_roller, m.node_theta, m.node_radius, m.node_sense, m.z0)
    lin = jnp.einsum("nbq,q->nb", m.R, chi.reshape(-1))
    np.testing.assert_allclose(np.asarray(g), np.asarray(lin), atol=1e-11)
    # and differs at second order for a finite tilt
    chi2 = jnp.zeros((3, 6)).at[1, 3].set(0.05).at[1, 4].set(0.05)
    g2 = exact_static_displacement(chi2, m.node_roller, m.node_theta, m.node_radius, m.node_sense, m.z0)
    assert float(jnp.max(jnp.abs(g2 - jnp.einsum("nbq,q->nb", m.R, chi2.reshape(-1))))) > 1e-5


def test_rejects_too_coarse_2d_grid():
    with pytest.raises(jb.SceneError, match="at least 5"):
        jb.build_model(scene_with(lambda d: d["mesh"].update(n_xi=60), "three-roller"))


def test_unknown_variant_roller():
    import tomllib

    with pytest.raises(jb.SceneError, match="no roller of that name"):
        from jaxbelt.scene import _extend

        _extend(tomllib.loads('extends = "three-roller"\n[variant."nope"]\nrotation_mrad = [1.0, 0.0, 0.0]'), "x")


def test_roller_reactions_balance_and_vanish_at_dynamic_dofs():
    """Post-processed support loads: the equations of dynamic DOFs hold (residual ≈ 0); the
    in-plane support forces of all rollers plus the applied force sum to zero in steady state
    (the belt carries no other load); the drive delivers no torque without losses."""
    m, _ = small("three-roller-tension")
    _, tr = simulate(m, 156, name="three-roller-tension")
    reac = np.asarray(tr.roller_reaction)[-1]  # (p, 6)
    dyn = np.asarray(m.dynamic).reshape(3, 6)
    assert np.max(np.abs(reac[dyn])) < 1e-6 * 200.0
    total = reac[:, :2].sum(axis=0) + np.asarray(m.Q_ext).reshape(3, 6)[:, :2].sum(axis=0)
    assert np.max(np.abs(total)) < 1e-3 * 200.0
    assert abs(reac[0, 5]) < 1e-3  # drive torque, N·m
    assert np.max(np.abs(reac[0, :2])) > 10.0  # the drive's support really carries the belt tension


def test_belt_running_off_a_roller_is_reported_with_step_and_roller(tmp_path, capsys):
    """A 400 mm belt on 402 mm rollers walks sideways on a twisted roller (lateral transport):
    the edge margin starts at 1 mm, falls, and the CLI names the roller and the step where it
    turns negative."""
    from jaxbelt.cli import main

    path = tmp_path / "narrow.toml"
    path.write_text('extends = "three-roller"\n[mesh]\nn_eta = 3\n[time]\nt_end_s = 12.0\n'
                    '[solver]\nlateral_transport = true\n'
                    '[variant."roller 1"]\nwidth_mm = 402.0\n[variant."roller 2"]\nwidth_mm = 402.0\n'
                    'rotation_mrad = [5.0, 0.0, 0.0]\n[variant."roller 3"]\nwidth_mm = 402.0\n')
    assert main(["simulate", str(path), "--json"]) == 0
    out = capsys.readouterr()
    import json

    off = json.loads(out.out)["belt_off_roller"]
    assert off is not None and off["margin_um"] < 0 and 0 < off["step"] <= 600
    assert f"runs off {off['roller']!r} at step {off['step']}" in out.err
