"""Stability at the extremes: the CFL limit, the NaN/inf guard, long runs, stiffness and density
from soft rubber to steel. Each case either works within a stated error or fails with one
clear line."""

import copy
import json
import math
import tomllib
from importlib import resources

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from helpers import load, solve_step
from jaxbelt.cli import main
from jaxbelt.mesh import build_mesh
from jaxbelt.state import start_swing
from jaxbelt.run_checks import belt_speed


def base_1d():
    return tomllib.loads((resources.files("jaxbelt") / "scenes" / "two-roller-1d.toml").read_text())


def scene_1d(**over):
    d = copy.deepcopy(base_1d())
    for table, kv in over.items():
        d.setdefault(table, {}).update(kv)
    return jb.scene_from_dict(d)


def cfl_limit(sc):
    mesh = jb.build_mesh(sc)
    V = max(r.speed for r in sc.rollers if r.role == "drive")
    return float(mesh.ell.min()) / V


def test_dt_just_below_the_cfl_limit_runs_and_just_above_is_rejected():
    sc = scene_1d()
    dt_max = cfl_limit(sc)
    ok = scene_1d(time={"dt_s": 0.99 * dt_max, "t_end_s": 50 * 0.99 * dt_max})
    model, opts = load(ok)
    _, tr = jb.simulate(model, **opts)
    assert np.all(np.isfinite(np.asarray(tr.tracer_u)))
    m = np.asarray(tr.belt_mass)
    assert np.max(np.abs(m / m[0] - 1)) < 1e-13
    # the shift rule's weight is s / ℓ with s the belt's mean motion in the step: it settles at
    # V Δt / ℓ_min = 0.99; during the start-up the belt's mean speed overshoots V by ~2 %, and the
    # weight reaches ~1.01 for two steps (a 1 % extrapolation the CLI reports as a warning)
    w = np.asarray(tr.transport_weights)
    assert w.min() >= 0.0 and w.max() < 1.02
    assert np.all(w[10:] < 1.0) and w[-1, 1] == pytest.approx(0.99, abs=1e-6)
    with pytest.raises(jb.SceneError, match=r"time\.dt_s .*CFL.*use dt_s <="):
        jb.build_mesh(scene_1d(time={"dt_s": 1.01 * dt_max, "t_end_s": 1.0}))  # before any compile
    with pytest.raises(ValueError, match=r"CFL.*use dt <="):  # a run of the model at such a step: refused too
        jb.simulate(model, opts.solver, n_steps=opts.n_steps, dt=1.01 * dt_max)


def test_nonfinite_state_stops_with_step_and_cause():
    model, opts = load(scene_1d(time={"t_end_s": 0.1}))
    run = dict(solver=opts.solver, dt=opts.dt)
    st = jb.initial_state(model)
    bad = st.__class__(u=st.u.at[7, 0].set(jnp.nan), u_dot=st.u_dot, chi=st.chi, chi_dot=st.chi_dot,
                       m_e=st.m_e, step=st.step)
    with pytest.raises(jb.NonFiniteStateError, match=r"non-finite belt displacement at step 1 \(t = 0\.005 s\)"):
        jb.simulate(model, y0=bad, n_steps=30, **run)  # 30 steps: a run length other modules compile too
    # under jit the flag travels with the trajectory and the caller checks it
    tr = jax.jit(lambda s: jb.simulate(model, y0=s, n_steps=10, **run)[1])(bad)
    assert np.asarray(tr.nonfinite)[0] == 1
    with pytest.raises(jb.NonFiniteStateError):
        jb.check_finite(tr, opts.dt)
    # a healthy run passes the guard: every step's flag is 0
    _, tr = jb.simulate(model, n_steps=30, **run)
    assert not np.any(np.asarray(tr.nonfinite))


def test_long_run_keeps_mass_and_mean_displacement():
    """10 000 steps (50 s; the 100 000-step version is marked slow): no drift of the belt mass or
    of the mean tracer displacement once the belt has settled."""
    model, opts = load(scene_1d(time={"t_end_s": 50.0}, output={"every": 100}))
    _, tr = jb.simulate(model, **opts)
    m = np.asarray(tr.belt_mass)
    assert np.max(np.abs(m / m[0] - 1)) < 1e-12
    mean_u = np.asarray(tr.tracer_u).mean(axis=1)
    assert np.ptp(mean_u[len(mean_u) // 2:]) < 1e-9  # m


def test_100000_steps_keep_mass_and_mean_displacement():
    model, opts = load(scene_1d(time={"t_end_s": 500.0}, output={"every": 500}))
    _, tr = jb.simulate(model, **opts)
    m = np.asarray(tr.belt_mass)
    assert len(m) == 200
    assert np.max(np.abs(m / m[0] - 1)) < 1e-11
    mean_u = np.asarray(tr.tracer_u).mean(axis=1)
    assert np.ptp(mean_u[len(mean_u) // 2:]) < 1e-9


@pytest.mark.parametrize("E, rho", [(1e6, 1100.0), (2.5e9, 1420.0), (2.1e11, 7850.0)])
def test_stiffness_over_five_orders_of_magnitude(E, rho):
    """Soft rubber (1 MPa) to steel (210 GPa), idle roller moved 1 mm out: the static solution has
    the hand-calculated strain d / D in both spans whatever the stiffness (to 1e-9), and a 6 s run
    stays finite and conserves mass. Where the belt is stiff enough for Backward Euler's damping to
    settle the start-up within the run (E ≥ 2.5 GPa here), the running strain is the analytic
    d / (D + π r); the rubber belt's slowest mode (EA = 5 N against the rollers' inertia) is still
    ringing after 6 s — the model has no material damping."""
    import dataclasses

    from helpers import span_strains, whole_chunks

    sc = jb.load_scene("two-roller-1d-idle-translated")
    sc = sc.replace(belt=dataclasses.replace(sc.belt, youngs_modulus=E, density=rho))
    mesh = jb.build_mesh(sc)
    model = jb.build_model(sc, mesh)
    for e in span_strains(model, mesh, jb.initial_state(model).u):
        np.testing.assert_allclose(e, 1e-3 / 0.275, rtol=1e-9)
    integ, dt = jb.make_solver("direct"), sc.time.dt
    # 1225 steps (6.1 s): whole checkpoint chunks, the compiled run of test_transport.py's 6 s runs
    s, tr = jb.simulate(model, integ, n_steps=whole_chunks(1200), dt=dt)
    assert not np.any(np.asarray(tr.nonfinite))
    m = np.asarray(tr.belt_mass)
    assert np.max(np.abs(m / m[0] - 1)) < 1e-12
    if E >= 2.5e9:
        for e in span_strains(model, mesh, solve_step(model, integ, s, dt).u):
            np.testing.assert_allclose(e, 1e-3 / (0.275 + np.pi * 0.05), rtol=1e-9)


def test_span_forces_of_a_pretensioned_belt_are_E_A_eps0():
    from jaxbelt.prestress import slack_spans, span_forces

    sc = jb.load_scene("two-roller-1d-pretension")
    mesh = jb.build_mesh(sc)
    model = jb.build_model(sc, mesh)
    eps0 = mesh.length / sc.belt.length - 1.0
    for s in span_forces(sc, mesh, model):
        assert s["force_n"] == pytest.approx(sc.belt.youngs_modulus * sc.belt.area * eps0, rel=1e-9)
    assert slack_spans(sc, mesh, model) == []


def test_slack_belt_is_detected_and_located(tmp_path, capsys):
    """Roller 2 of the three-roller machine moved 50 mm inwards: the belt is ~100 mm too long; the
    static solution puts the spans under net compression and simulate warns with 'slack' and the
    spans; moved outwards (tensioned) nothing is reported."""
    from jaxbelt.cli import main
    from jaxbelt.prestress import slack_spans

    d = tomllib.loads((resources.files("jaxbelt") / "scenes" / "three-roller.toml").read_text())
    d["mesh"].update(n_eta=3)
    for dx, slack in ((-50.0, True), (5.0, False)):
        d["roller"][1]["translation_mm"] = [dx, 0.0, 0.0]
        sc = jb.scene_from_dict(d)
        mesh = jb.build_mesh(sc)
        found = slack_spans(sc, mesh, jb.build_model(sc, mesh))
        assert bool(found) == slack
        if slack:
            assert {s["span"] for s in found} >= {"roller 1 → roller 2", "roller 2 → roller 3"}
            assert all(s["strain"] < -1e-3 for s in found)
    # the CLI warns before it runs
    p = tmp_path / "slack.toml"
    p.write_text('extends = "two-roller-1d"\n[variant."idle"]\ntranslation_mm = [-2.0, 0.0, 0.0]\n'
                 '[time]\nt_end_s = 0.05\n')
    assert main(["simulate", str(p), "--json"]) == 0
    err = capsys.readouterr().err
    assert "slack belt" in err and "drive → idle" in err


def test_overstrained_belt_is_detected(tmp_path, capsys):
    """The idle roller of two-roller-1d moved 30 mm outwards: in the static solution (the belt held
    on the rollers) each free span of length D stretches by d / D ≈ 11 %, beyond the small-strain
    model's 5 %: reported with the spans, and simulate warns; 5 mm out (≈ 1.8 %) is not reported."""
    from jaxbelt.cli import main
    from jaxbelt.prestress import STRAIN_LIMIT, overstrained_spans

    d = tomllib.loads((resources.files("jaxbelt") / "scenes" / "two-roller-1d.toml").read_text())
    drive, idle = d["roller"]
    D = math.dist(drive["center_mm"], idle["center_mm"])
    for dx in (30.0, 5.0):
        idle["translation_mm"] = [dx, 0.0, 0.0]
        sc = jb.scene_from_dict(d)
        mesh = jb.build_mesh(sc)
        found = overstrained_spans(sc, mesh, jb.build_model(sc, mesh))
        expected = dx / D
        assert bool(found) == (expected > STRAIN_LIMIT)
        for span in found:
            assert span["strain"] == pytest.approx(expected, rel=0.05)
    p = tmp_path / "stretched.toml"
    p.write_text('extends = "two-roller-1d"\n[variant."idle"]\ntranslation_mm = [30.0, 0.0, 0.0]\n'
                 '[time]\nt_end_s = 0.05\n')
    assert main(["simulate", str(p), "--json"]) == 0
    captured = capsys.readouterr()
    assert "stretched beyond 5 %" in captured.err and "drive → idle" in captured.err
    assert json.loads(captured.out)["overstrained"]


def test_rotation_beyond_the_linear_range_is_refused_and_near_it_warned():
    """benchmarks/linearity_range.py: the response's linearity error is ≈ 0.64 α for a skew; above
    10 mrad a scene warns, above 50 mrad it is refused (a 0.1 rad skew used to run silently)."""
    d = tomllib.loads((resources.files("jaxbelt") / "scenes" / "three-roller.toml").read_text())
    for mrad, outcome in ((5.0, "ok"), (20.0, "warn"), (100.0, "refuse")):
        d["roller"][1]["rotation_mrad"] = [0.0, mrad, 0.0]
        if outcome == "refuse":
            with pytest.raises(jb.SceneError, match=r"roller.*rotation_mrad.*range of 50 mrad"):
                jb.scene_from_dict(d)
            continue
        import warnings

        with warnings.catch_warnings(record=True) as w:
            warnings.simplefilter("always")
            jb.scene_from_dict(d)
        hits = [x for x in w if issubclass(x.category, jb.scene.MisalignmentWarning)]
        assert len(hits) == (outcome == "warn")


def test_linearity_error_grows_with_the_skew_as_measured():
    """The figure behind the range: on a coarse three-roller the skew response's linearity error at
    10 mrad is 0.3–1 % and at 1 mrad ten times smaller."""
    d = tomllib.loads((resources.files("jaxbelt") / "scenes" / "three-roller.toml").read_text())
    d["mesh"].update(n_eta=3)
    d["time"].update(t_end_s=0.4)
    d["solver"] = {"linear_solver": "reuse"}
    model, opts = load(jb.scene_from_dict(d))
    _, ref = jb.simulate(model, **opts)

    def resp(a):
        _, tr = jb.simulate(jb.with_misalignment(model, rotation=jnp.zeros((3, 3)).at[1, 1].set(a)), **opts)
        return np.concatenate([np.asarray(tr.tracer_u[-1] - ref.tracer_u[-1]), np.asarray(tr.tracer_v[-1] - ref.tracer_v[-1])])

    s0 = resp(1e-6) / 1e-6
    err = lambda a: np.linalg.norm(resp(a) / a - s0) / np.linalg.norm(s0)  # noqa: E731
    e1, e10 = err(1e-3), err(1e-2)
    assert 3e-3 < e10 < 1e-2
    assert e1 == pytest.approx(e10 / 10, rel=0.1)


# --- float32 and the reduced models at the edges -------------------------------------------------

def test_float32_end_to_end_error_is_small():
    """Without :func:`jaxbelt.enable_x64` the whole model runs in float32 (a subprocess: x64 is
    process-wide); on two-roller-1d-train1 over 400 steps the tracers differ from float64 by
    < 1e-3 of the response (benchmarks/float32.py: 4.4e-4 over 1000 steps, 6.4e-4 on
    three-roller-t72 over 5000)."""
    import os
    import subprocess
    import sys

    code = ("import numpy as np, jaxbelt as jb\n"
            "sc = jb.load_scene('two-roller-1d-train1')\n"
            "_, tr = jb.simulate(jb.build_model(sc), n_steps=400, dt=sc.time.dt)\n"
            "print(tr.tracer_u.dtype)\n"
            "print(' '.join(repr(float(x)) for x in np.asarray(tr.tracer_u[-1])))\n")
    r = subprocess.run([sys.executable, "-c", code], env={**os.environ, "JAX_ENABLE_X64": "0"},
                       capture_output=True, text=True, check=True)
    dtype, values = r.stdout.strip().splitlines()[-2:]
    assert dtype == "float32"
    u32 = np.array([float(v) for v in values.split()])
    model, opts = load("two-roller-1d-train1")
    _, tr = jb.simulate(model, opts.solver, n_steps=400, dt=opts.dt)
    u64 = np.asarray(tr.tracer_u[-1])
    assert np.max(np.abs(u32 - u64)) < 1e-3 * np.max(np.abs(u64))


def _linear_trajectory(n=8, m=60, seed=1, growth=None):
    rng = np.random.default_rng(seed)
    Q = np.linalg.qr(rng.normal(size=(n, n)))[0]
    lam = np.linspace(0.6, 0.97, n) if growth is None else np.r_[np.linspace(0.6, 0.95, n - 1), growth]
    A = Q @ np.diag(lam) @ Q.T
    X = np.zeros((n, m))
    X[:, 0] = rng.normal(size=n)
    for k in range(m - 1):
        X[:, k + 1] = A @ X[:, k]
    return A, lam, X


def test_dmd_on_duplicated_rank_deficient_and_noisy_snapshots():
    from jaxbelt.rom import fit_dmd

    A, lam, X = _linear_trajectory()
    # duplicated state rows (a rank-deficient snapshot matrix, N = 16, rank 8): same eigenvalues
    d = fit_dmd(jnp.asarray(np.vstack([X, X])))
    assert np.allclose(np.sort(np.abs(np.asarray(d.eigs))), np.sort(lam), atol=1e-8)
    pred = np.asarray(d.predict(jnp.asarray(np.vstack([X, X])[:, 0]), 10))
    assert np.all(np.isfinite(pred)) and np.allclose(pred[:, :8], X[:, 1:11].T, atol=1e-8)
    # zero rows (unexcited DOFs) change nothing
    d0 = fit_dmd(jnp.asarray(np.vstack([X, np.zeros((5, X.shape[1]))])))
    assert np.allclose(np.sort(np.abs(np.asarray(d0.eigs))), np.sort(lam), atol=1e-8)
    # noise of 1e-6 of the largest snapshot entry: the slowest mode (which dominates the late
    # snapshots) stays within 1e-4, the next within 2e-3; the fast ones, decayed below the noise
    # after a few steps, are biased by up to ~2e-2 (DMD's known noise bias) — finite and stable
    rng = np.random.default_rng(3)
    dn = fit_dmd(jnp.asarray(X + 1e-6 * np.abs(X).max() * rng.normal(size=X.shape)), rank=8)
    got = np.sort(np.abs(np.asarray(dn.eigs)))
    assert abs(got[-1] - lam.max()) < 1e-4 and abs(got[-2] - np.sort(lam)[-2]) < 2e-3
    assert np.allclose(got, np.sort(lam), atol=3e-2) and np.all(got < 1.0)


def test_dmd_growing_mode_is_found_and_dropped_by_stable():
    from jaxbelt.rom import fit_dmd

    _, lam, X = _linear_trajectory(growth=1.02)
    d = fit_dmd(jnp.asarray(X))
    assert np.max(np.abs(np.asarray(d.eigs))) == pytest.approx(1.02, abs=1e-8)
    s = d.stable()
    assert np.max(np.abs(np.asarray(s.eigs))) < 1.0 and len(s.eigs) == len(lam) - 1


def test_pod_asking_for_more_modes_than_snapshots_keeps_all_and_is_exact():
    """n_modes beyond min(N, m) is clamped to the snapshots' rank: the basis then spans every
    snapshot and reproduces it to round-off (documented in pod_basis)."""
    from jaxbelt.rom import pod_basis

    _, _, X = _linear_trajectory(n=30, m=12)
    V, s = pod_basis(jnp.asarray(X), n_modes=50)
    V = np.asarray(V)
    assert V.shape == (30, 12) and len(s) == 12
    assert np.allclose(V @ (V.T @ X), X, atol=1e-12 * np.abs(X).max())


def _t72_run(n_eta):
    import dataclasses

    sc = jb.load_scene("three-roller-t72")
    sc = sc.replace(mesh=dataclasses.replace(sc.mesh, n_eta=n_eta), solver=dataclasses.replace(sc.solver, linear_solver="reuse"))
    model, opts = load(sc, n_steps=20)
    _, tr = jb.simulate(model, **opts)
    return tr


@pytest.fixture(scope="module")
def t72_default_grid():
    return _t72_run(18)


@pytest.mark.parametrize("n_eta", [2, 33])
def test_very_coarse_and_very_fine_grids_across_the_width(n_eta, t72_default_grid):
    """three-roller-t72 with 2 and 33 points across (N = 1266 … 6882), 20 steps: finite, mass
    conserved, and the tracers within 10 % of the default 18-point grid's (the corner-limited
    convergence of test_validation makes the coarse grid the worst). The fine grid (N = 6882, a
    size check) is slow; test_validation's n_η = 3/5/9 convergence runs refine the width fast."""
    tr, ref = _t72_run(n_eta), t72_default_grid
    m = np.asarray(tr.belt_mass)
    assert np.max(np.abs(m / m[0] - 1)) < 1e-13
    for a, b in ((tr.tracer_u, ref.tracer_u), (tr.tracer_v, ref.tracer_v)):
        a, b = np.asarray(a[-1]), np.asarray(b[-1])
        assert np.max(np.abs(a - b)) < 0.1 * np.max(np.abs(b))


def _idle_translated():
    sc = jb.load_scene("two-roller-1d-idle-translated")
    return jb.build_model(sc), jb.RunOptions.from_scene(sc)


def test_small_time_steps_converge_from_a_running_start():
    """From a running start (belt and idle roller at the drive speed, consistent with no slip) the
    1D machine with its idle roller 1 mm out converges at first order as Δt → 0 on a fixed grid:
    Δt, Δt/10, Δt/100 and Δt/1000 (Courant numbers 0.64 down to 6.4e-4) differ by a tenth as much
    at each level, and the idle roller turns with the drive."""
    model, opts = _idle_translated()
    y0 = jb.initial_state(model, start="running")
    ends = []
    for k in (1, 10, 100, 1000):
        n = 40 * k
        final, tr = jb.simulate(model, opts.solver, n_steps=n, dt=opts.dt / k, y0=y0, saveat=jb.SaveAt(every=n))
        ends.append(np.asarray(tr.tracer_u[-1]) * 1e6)
        assert abs(float(final.chi_dot[-1]) / float(final.chi_dot[1]) - 1.0) < 1e-4
    gaps = [np.abs(a - b).max() for a, b in zip(ends, ends[1:])]
    assert gaps[0] > 1.0  # µm: the coarse step's own error is visible
    assert gaps[1] < 0.15 * gaps[0] and gaps[2] < 0.15 * gaps[1], gaps


def test_small_time_steps_converge_from_a_running_start_in_2d():
    """The misaligned 2D machine (``three-roller-t72``) from a running start: Δt, Δt/10 and Δt/100
    (Courant 0.77 down to 7.7e-3) differ by a tenth as much at each level over 0.2 s, and every
    idle roller's surface keeps to the belt speed (no slip; ``benchmarks/small_time_steps.py``)."""
    sc = jb.load_scene("three-roller-t72")
    model, opts = jb.build_model(sc), jb.RunOptions.from_scene(sc)
    y0 = jb.initial_state(model, start="running")
    az, V = model.dofs.index("az"), belt_speed(model)
    ends = []
    for k in (1, 10, 100):
        n = int(round(0.2 / (opts.dt / k)))
        _, tr = jb.simulate(model, opts.solver, n_steps=n, dt=opts.dt / k, y0=y0, saveat=jb.SaveAt(every=n))
        ends.append(np.asarray(tr.tracer_u[-1]) * 1e6)
        rv = np.asarray(tr.roller_velocity)[-1]
        slip = max(abs(abs(rv[j, az]) * r.radius / V - 1.0) for j, r in enumerate(sc.rollers) if r.role != "drive")
        assert slip < 1e-3, (k, slip)
    gaps = [np.abs(a - b).max() for a, b in zip(ends, ends[1:])]
    assert gaps[0] > 1.0 and gaps[1] < 0.15 * gaps[0], gaps


def test_a_start_from_rest_swings_the_idle_roller_at_its_torsional_frequency():
    """From rest (model specification §2) the impulsive start sets the idle roller swinging on the
    two spans, undamped but for Backward Euler's numerical damping: at a small Δt the swing has the
    torsional frequency of the roller's inertia on the spans' stiffness, √(2 EA / L / (m_r / 2)) —
    physics, not an error — and its mean speed is the drive's (no slip)."""
    sc = jb.load_scene("two-roller-1d")
    model = jb.build_model(sc)
    dt, n = 2e-5, 2500
    _, tr = jb.simulate(model, jb.RunOptions.from_scene(sc).solver, n_steps=n, dt=dt)
    w = np.asarray(tr.roller_velocity)[:, 1, -1]  # idle roller's α̇_z, rad/s
    belt = sc.belt
    EA = belt.youngs_modulus * belt.width * belt.thickness
    span = np.hypot(*np.subtract(sc.rollers[1].center, sc.rollers[0].center))
    omega_t = math.sqrt(2 * EA / span / (0.5 * sc.rollers[1].mass))
    up = np.flatnonzero((w[:-1] < 10.0) & (w[1:] >= 10.0))  # upward crossings of the drive's speed
    period = np.mean(np.diff(up)) * dt
    assert abs(2 * math.pi / period / omega_t - 1) < 0.03, (2 * math.pi / period, omega_t)
    assert w.max() > 18.0 and w.min() < 2.0  # swinging between rest and twice the drive speed
    whole = slice(up[0], up[-1])
    assert abs(np.mean(w[whole]) / 10.0 - 1) < 0.01
    # start_swing predicts the frequency and what Backward Euler leaves of the swing's amplitude
    (name, f, left), = start_swing(sc, build_mesh(sc), dt, n)
    assert name == "idle" and abs(2 * math.pi * f / omega_t - 1) < 1e-12
    last = w[up[-2]:up[-1]]
    amplitude = 0.5 * (last.max() - last.min())
    assert abs(amplitude / (10.0 * left) - 1) < 0.05, (amplitude, left)


def test_a_run_that_keeps_the_start_up_swing_is_warned_about(capsys):
    """``jaxbelt simulate`` from rest names the swing a small Δt keeps (and says how to start
    running); at the scene's own Δt, where Backward Euler removes it within a few steps, it is silent."""
    assert main(["simulate", "two-roller-1d", "--t-end", "0.05", "--dt", "5e-5", "--json"]) == 0
    err = capsys.readouterr().err
    assert "start-up swing (~96 Hz)" in err and "--start running" in err
    assert main(["simulate", "two-roller-1d", "--t-end", "0.05", "--json"]) == 0
    assert "swing" not in capsys.readouterr().err
    assert main(["simulate", "two-roller-1d", "--t-end", "0.05", "--dt", "5e-5", "--start", "running", "--json"]) == 0
    assert "swing" not in capsys.readouterr().err
