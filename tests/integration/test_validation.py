"""Validation set: fast physical checks of the model against independent analytic values.

The lateral belt mechanics checked against theory. Every check compares a
measured number with a value derived by hand (not by the model), with its tolerance in the test.
``benchmarks/validation.py`` runs the same measurement functions at finer resolution and writes
``benchmarks/results/validation.json`` and ``.png``. Numbers are at the test's resolution
unless marked "benchmark".

1. **Longitudinal wave speed** ``c = √(E/ρ)`` = 1326.86 m/s. The grid is fixed in space, so the
   tracers are spatial probes and a pulse in a belt running at V passes them at ``c ± V``. "At
   rest" is a drive speed of 1e-6 m/s (a drive needs V > 0; V/c ~ 1e-9). Both rollers drive and
   every belt node starts at the belt speed, so the run starts without a shock. A Gaussian
   displacement pulse (σ = 20 mm) in the middle of a 1 m span splits into two halves; the speed
   is the distance between two tracers (100 and 400 mm from the pulse, on each side) over the
   difference of the peak arrival times. At h = 5 mm, c Δt = 2 mm: −0.41 % (1D); with V = 100
   m/s downstream c + V − 0.38 %, upstream c − V − 0.62 %, V = 101.05 m/s from (c↓ − c↑)/2. The
   error is numerical dispersion (lumped-mass elements and Backward Euler both slow short waves
   down), benchmark: −0.41 … −0.59 % at h = 5 mm for c Δt = 0.5 … 4 mm, −0.18 % at 2.5 / 1 mm,
   −0.066 % at 1.25 / 0.5 mm (there c ± V to −0.07 / −0.14 %, V = 100.4 m/s); at h = 10 mm it is
   −0.8 … −1.6 % and grows as Δt shrinks (BE's damping of the slow short waves then stops
   helping), so h ≤ σ/4 is what keeps it well inside the 2 % tolerance.
   *2D:* with ν = 0 the 2D model is the 1D model (the same tracer history to 3e-14). With
   ν = 0.34 a narrow belt (10 mm ≪ σ) gives the bar speed (−0.51 %), but a **wide** belt
   (400 mm ≫ σ) gives the plate speed ``c/√(1 − ν²)`` = 1.064 c (+0.09 % of it): the middle of
   a wide belt cannot contract laterally while the pulse passes, so ``√(E/ρ)`` is not the right
   reference there. The model is right; the test checks both limits. In between (belt width
   2.5–10 σ, benchmark) the pulse disperses over the strip's lateral modes and its peak moves
   at 0.87–1.08 c: no single speed to check; already at 50 mm (2.5 σ) it is −2.7 %.
2. **Static tension.** A belt shorter than its path carries ``T = E A ε₀`` in every span and a
   roller's support supplies ``−T (t_out − t_in)`` (``roller_reaction`` is the support's force).
   1D ``two-roller-1d-pretension``: ±2T = ±14.481 N to 8e-10 T; 2D ``three-roller`` with
   ``length_mm = 2830`` (T = 172.8 N) against tangents computed here from the roller centres
   and radii, to 3e-7 T after 36 steps. Tension rollers (``two-roller-1d-tension``,
   ``three-roller-tension``, 156 steps): T = F / |(t_out − t_in)·x̂| at the pulled roller
   (50 N; 115.15 N), the same T at the others, span tension F/2 in 1D. **Drive torque**: without losses the
   steady torque is 0 (< 1e-13 N·m in 1D, 5e-9 N·m in 2D), and what the drive delivers during
   the start-up is the angular momentum it gives the rest of the loop,
   ``∫τ dt = r₁ V (m_belt − m_on_drive + Σ_idle I_j / r_j²)``: 2e-12 (1D), 3e-9 (2D),
   3e-6 with a tension roller (it moves during the start-up).
3. **Lateral translation of a roller** (2D, two rollers 1 m apart, r = 80 mm, 50 × 0.3 mm belt,
   roller 2 moved by d = 1 mm along its axis). The belt on roller 2 moves by d exactly. At rest
   each span is a strip clamped at both contact lines (every node of a contact line is pinned
   by no-slip, so this is not a rigid-body follow), i.e. a clamped-guided Timoshenko beam,
   ``v = d (3ξ² − 2ξ³ + φ ξ) / (1 + φ)``, ``φ = 12 EI / (κ G A L²)`` = 0.008, and roller 2
   carries ``2 · 12 EI d / (L³ (1 + φ))`` = 0.1860 N. Measured: shape within 5.8e-4 d, support
   +0.61 % (the 2D contact line also stops warping: stiffer than the beam's clamp; the whole
   shear part is φ = 0.8 %, hence tolerances 1 % d and 2 %). Pre-tensioned (ε₀ = 1e-3, K L =
   2.19) the span is the tensioned beam ``EI v'''' − T v'' = 0`` (tension stiffening): shape
   within 3.1e-4 d, support −0.12 %.
   *Running belt* — the model and the static theory part ways, for reasons the model gets
   right within its variant: in the default variant (``lateral_transport = false``, the
   source's) u is transported and v is not, so the cross-section rotation ``u = −z θ`` is
   carried round the rollers while the lateral position stays put, and a contact node takes its
   value from the node upstream (zero curvature at the entry). The steady state is then the
   beam with ``v(0) = 0``, ``θ(0)`` = the rotation carried round roller 1 from the end of span 2,
   ``M(L) = 0``, ``v(L) = d`` (mirrored in span 2), solved by ``v = d (−3ξ + 6ξ² − 2ξ³)``: the
   span leaving the fixed roller swings to −0.41 d, the other to +1.41 d, independent of Δt,
   V and ν, with the same support load (the ξ³ term is −2 d in both). Measured within 2.1 % d
   (benchmark: 1.3 % and 0.87 % on meshes 2 and 4 times finer; tolerance 3 % d). With
   ``lateral_transport = true`` an axially translated cylinder does not steer (Shelton & Reid:
   normal entry, zero entry moment), so the spans straighten and the support load vanishes
   (``slow`` test; benchmark: spread 8e-5 d and load 4e-5 of the static one after 12 loops).
4. **Observed convergence orders** on ``three-roller-t72`` (n_ξ = 104, tracer displacements at
   t = 0.72 s; ``K_σ = 0`` without tension, so tension stiffening is switched off to save its
   compile; orders from three levels, ``log2(|y₁ − y₂| / |y₂ − y₃|)``). Δt 0.02/0.01/0.005:
   Backward Euler, expected 1, observed 1.000 (u) and 1.05 (v). n_η 3/5/9: the bilinear (or
   QM6) element is second order for smooth fields, but where a pinned contact line meets a free
   edge the solution has the clamped–free corner singularity ``r^λ``,
   ``κ² + 1 + 2κ cos(λπ) = 4λ²`` (κ = (3 − ν)/(1 + ν), plane stress), λ = 0.742, which limits
   the error at interior points to ``O(h^{2λ}) = O(h^1.48)``: expected 1.5–2, observed 1.58 (u)
   and 1.37 (v) (benchmark, against an n_η = 33 truth: u 1.50, 1.42, 1.66; v 1.50, 1.76, 2.03).
   n_ξ with Δt ∝ ℓ (fixed Courant number; the CFL condition ties them): first-order upwind
   transport and BE, expected ≥ 1, observed 1.42 (u) and 1.05 (v) on 208/416/832 (``slow``;
   benchmark against n_ξ = 3328: u 0.75, 1.41, 1.41; v 1.38, 1.10, 1.17 from n_ξ = 104 up).
5. **Numerical damping of Backward Euler.** Discrete sine modes of a span between two drive
   rollers are exact eigenvectors of the model's own ``K`` and ``M`` (``assembly.dae_apply``;
   with both rollers driven no constrained DOF depends on a free one, so these are the condensed
   ``K̂ = K_ff``, ``M̂ = M_ff``; residual < 5e-13) with ``ω_k = (2c/h) sin(kπ/2n)``. BE maps a
   free mode to ``x_n = ρⁿ cos(n atan θ)``, ``ρ = (1 + θ²)^(−1/2)``, θ = ω Δt, so its energy
   ``½(ω² x² + ẋ²)`` falls by exactly ``1/(1 + θ²)`` per step. Five modes at once, θ = 0.013 …
   0.79: amplitude and phase to 9e-10 of the initial amplitude, energy ratio to 4e-9
   (benchmark up to θ = 7.9: 2e-8).
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbelt as jb
from helpers import scene_with, span_strains, whole_chunks
from jaxbelt.assembly import dae_apply
from jaxbelt.timeloop import tracer_values

E, RHO, NU = 2.5e9, 1420.0, 0.34  # the built-in scenes' belt material
C0 = math.sqrt(E / RHO)  # bar speed, m/s
REST = 1e-6  # m/s: "at rest" (a drive needs a positive speed)
# A belt without tension has no initial-stress stiffness (K_σ = 0 exactly); switching it off only
# saves its compile-time static solve. 1D scenes have no such option.
NO_TENSION = {"tension_stiffening": False}


# ----------------------------------------------------------------------------- scenes


def two_roller(kind="1d", span_mm=1000.0, radius_mm=50.0, width_mm=50.0, thickness_mm=0.1, nu=NU,
               arc=8, span=200, n_eta=5, dt=1e-3, speed=REST, second="drive", **tables):
    """``two-roller-1d`` edited: rollers ``span_mm`` apart, ``arc`` / ``span`` elements per arc /
    span, roller 2 a drive too (the spans are then independent fixed–fixed bars) or ``second``.
    ``tables``: keys merged into those top-level tables (``belt``, ``output``, ``solver``, …)."""

    def mutate(d):
        d["model"] = {"kind": kind}
        d["belt"].update(width_mm=width_mm, thickness_mm=thickness_mm, poisson_ratio=nu)
        for r in d["roller"]:
            r.update(radius_mm=radius_mm, width_mm=width_mm + 10.0)
        d["roller"][0]["speed_m_s"] = speed
        d["roller"][1].update(center_mm=[span_mm, 0.0], role=second)
        if second == "drive":
            d["roller"][1]["speed_m_s"] = speed
        d["mesh"] = {"roller_elements": [arc, arc], "free_elements": [span, span]}
        if kind == "2d":
            d["mesh"]["n_eta"] = n_eta
        d["time"] = {"dt_s": dt, "t_end_s": 1.0}
        for name, values in tables.items():
            d.setdefault(name, {}).update(values)

    return scene_with(mutate, "two-roller-1d")


def compiled(scene):
    """``(model, mesh, run options)`` of a scene."""
    mesh = jb.build_mesh(scene)
    return jb.build_model(scene, mesh), mesh, jb.RunOptions.from_scene(scene)


# ----------------------------------------------------------------------------- 1. wave speed

PULSE_MM, SIGMA_MM, NEAR_MM, FAR_MM, R_WAVE_MM = 500.0, 20.0, 100.0, 400.0, 50.0


def wave_scene(kind="1d", h_mm=5.0, c_dt_mm=2.0, speed=REST, width_mm=50.0, nu=NU, n_eta=3):
    """Two drives 1 m apart; tracers 100 and 400 mm downstream, then upstream, of the pulse."""
    x0 = math.pi * R_WAVE_MM + PULSE_MM  # path coordinate: roller 1's half wrap comes first
    tracers = [[x0 + s * a, 0.0] for s in (1.0, -1.0) for a in (NEAR_MM, FAR_MM)]
    return two_roller(kind, radius_mm=R_WAVE_MM, width_mm=width_mm, nu=nu, n_eta=n_eta, span=round(1000.0 / h_mm),
                      dt=c_dt_mm * 1e-3 / C0, speed=speed, solver=NO_TENSION,
                      output={"tracers_per_segment": 0, "tracers_mm": tracers, "fields": "full"})


def wave_steps(dt):
    """Until the pulse has passed the far tracers (rounded up to whole checkpoint chunks)."""
    return whole_chunks(round((FAR_MM + 2 * SIGMA_MM) * 1e-3 / (C0 * dt)))


def moving_state(model, mesh, speed, extra_u):
    """The static state with every belt node at the belt speed and ``extra_u`` (n_xi,) added to
    the longitudinal displacement of every row."""
    s = jb.initial_state(model)
    u, ud = np.array(s.u), np.zeros(s.u.shape)
    u[:, 0::2] += extra_u[:, None]  # 1D: the only column; 2D: the u of every row
    ud[:, 0::2] = speed
    return eqx.tree_at(lambda s: (s.u, s.u_dot), s, (jnp.asarray(u), jnp.asarray(ud)))


def span1_coordinate(mesh):
    """Distance (n_xi,) of every node column from the start of span 1 (NaN off span 1)."""
    x = np.asarray(mesh.x) - mesh.path.segments[0].length
    return np.where((np.asarray(mesh.node_roller) < 0) & (x < mesh.path.segments[1].length), x, np.nan)


def peak_time(t, y):
    """Time of the maximum of ``y(t)``: parabola through the five samples around it."""
    k = int(np.argmax(y))
    a, b, _ = np.polyfit(t[k - 2:k + 3] - t[k], y[k - 2:k + 3], 2)
    return t[k] - b / (2 * a)


def wave_speeds(model, mesh, opts, speed):
    """``(downstream, upstream, tracer history)``: pulse speeds (m/s) between the tracers."""
    x = np.nan_to_num(span1_coordinate(mesh), nan=-1.0)
    g = np.where(x >= 0, 1e-6 * np.exp(-0.5 * ((x - PULSE_MM * 1e-3) / (SIGMA_MM * 1e-3)) ** 2), 0.0)
    _, tr = jb.simulate(model, **opts.replace(n_steps=wave_steps(opts.dt)), y0=moving_state(model, mesh, speed, g))
    t, tu = np.asarray(tr.t), np.asarray(tr.tracer_u)
    arrive = [peak_time(t, tu[:, k]) for k in range(4)]
    gap = (FAR_MM - NEAR_MM) * 1e-3
    return gap / (arrive[1] - arrive[0]), gap / (arrive[3] - arrive[2]), tu


@pytest.fixture(scope="module")
def wave_1d():
    model, mesh, opts = compiled(wave_scene("1d"))
    fast, _, _ = compiled(wave_scene("1d", speed=100.0))  # same static fields: the same compiled run
    return model, fast, mesh, opts


def test_wave_speed_1d_at_rest_and_moving(wave_1d):
    model, fast, mesh, opts = wave_1d
    down, up, _ = wave_speeds(model, mesh, opts, REST)
    assert down == pytest.approx(C0, rel=0.02) and up == pytest.approx(C0, rel=0.02)
    V = 100.0
    down, up, _ = wave_speeds(fast, mesh, opts, V)
    assert down == pytest.approx(C0 + V, rel=0.02) and up == pytest.approx(C0 - V, rel=0.02)
    assert (down - up) / 2 == pytest.approx(V, rel=0.05)  # the moving frame: arrivals shifted by V


@pytest.mark.reference
def test_wave_speed_2d_bar_and_plate_limits(wave_1d):
    model_1d, _, mesh_1d, opts_1d = wave_1d
    *_, history_1d = wave_speeds(model_1d, mesh_1d, opts_1d, REST)
    plate = C0 / math.sqrt(1 - NU**2)
    for width, nu, ref in ((50.0, 0.0, C0), (10.0, NU, C0), (400.0, NU, plate)):
        model, mesh, opts = compiled(wave_scene("2d", width_mm=width, nu=nu))
        down, up, history = wave_speeds(model, mesh, opts, REST)
        assert down == pytest.approx(ref, rel=0.02) and up == pytest.approx(ref, rel=0.02), (width, nu)
        if nu == 0.0:  # no Poisson coupling: the 2D belt is the 1D bar
            np.testing.assert_allclose(history, history_1d, rtol=0, atol=1e-12 * np.abs(history_1d).max())
        if width > 100.0:
            assert min(down, up) > 1.04 * C0  # the plate limit is not the bar speed


# ----------------------------------------------------------------------------- 5. BE damping

MODES = (2, 20, 60, 120, 180)


def be_damping(model, mesh, opts, modes=MODES, steps=40, amplitude=1e-7):
    """Free vibration of sine modes of span 1 (zero mean: the transport shift stays ~0).

    **Returns:** ``(theta (k,), eigen_residual (k,), amplitude_error (k,), energy_ratio (k, steps-1))``:
    the residual ``|Kφ − ω²Mφ| / |Kφ|`` with the model's DAE operators, the largest
    deviation of the modal amplitude from ``ρⁿ cos(n atan θ)``, the per-step energy ratios."""
    x = span1_coordinate(mesh)
    cols = np.flatnonzero(~np.isnan(x))
    n = len(cols) + 1
    h = mesh.path.segments[1].length / n
    i = np.arange(1, n)
    shapes = np.array([np.sin(k * np.pi * i / n) for k in modes])
    omega = 2 * C0 / h * np.sin(np.array(modes) * np.pi / (2 * n))
    residual = []
    for phi_span, w in zip(shapes, omega):
        phi = jnp.zeros((model.n_xi, 1)).at[cols, 0].set(phi_span)
        (Kx, _), (Mx, _) = dae_apply(model, model.m_e0, model.R, phi, jnp.zeros(model.n_roller_dofs))
        residual.append(float(jnp.linalg.norm(Kx - w**2 * Mx) / jnp.linalg.norm(Kx)))
    u0 = np.zeros(model.n_xi)
    u0[cols] = amplitude * shapes.sum(axis=0)
    dt = opts.dt
    _, tr = jb.simulate(model, **opts.replace(n_steps=wave_steps(dt)), y0=moving_state(model, mesh, REST, u0))
    U = np.concatenate([u0[None, cols], np.asarray(tr.u)[:steps, cols, 0]])
    q = U @ shapes.T / (shapes**2).sum(axis=1) / amplitude  # (steps+1, k)
    theta = omega * dt
    k = np.arange(steps + 1)[:, None]
    exact = (1 + theta**2) ** (-k / 2) * np.cos(k * np.arctan(theta))
    energy = 0.5 * (omega**2 * q[1:] ** 2 + (np.diff(q, axis=0) / dt) ** 2)
    return theta, np.array(residual), np.abs(q - exact).max(axis=0), (energy[1:] / energy[:-1]).T


def test_backward_euler_damps_each_mode_by_its_amplification_factor(wave_1d):
    model, _, mesh, opts = wave_1d
    theta, residual, amp_err, ratio = be_damping(model, mesh, opts)
    assert theta.min() < 0.02 and theta.max() > 0.75
    assert residual.max() < 1e-10  # the analytic ω is the model's own eigenvalue
    assert amp_err.max() < 1e-6  # amplitude and phase: x_n = ρⁿ cos(n atan θ)
    np.testing.assert_allclose(ratio, np.broadcast_to(1 / (1 + theta[:, None] ** 2), ratio.shape), rtol=1e-6)


# ----------------------------------------------------------------------------- 2. statics, torque

def path_geometry(centres, radii):
    """Unit span directions ``t_i`` (roller i → i+1) and the loop length of a CCW belt around
    internal rollers, from outer common tangents: the outward normal ``n`` of span i satisfies
    ``n · (c_j − c_i) = r_i − r_j``."""
    c, r = np.asarray(centres, float), np.asarray(radii, float)
    p = len(r)
    t, spans = [], []
    for i in range(p):
        j = (i + 1) % p
        D = np.linalg.norm(c[j] - c[i])
        e = (c[j] - c[i]) / D
        s = (r[i] - r[j]) / D
        n = math.sqrt(1 - s**2) * np.array([e[1], -e[0]]) + s * e
        t.append(np.array([-n[1], n[0]]))
        spans.append(D * math.sqrt(1 - s**2))
    cross = lambda a, b: a[0] * b[1] - a[1] * b[0]
    wraps = [np.mod(math.atan2(cross(t[i - 1], t[i]), t[i - 1] @ t[i]), 2 * np.pi) for i in range(p)]
    return t, sum(spans) + float(np.dot(r, wraps)), np.asarray(wraps)


def start_up_momentum(mesh, rho_A, V, masses, radii):
    """``r₁ V (m_belt − m_on_drive + Σ_idle I_j / r_j²)``, N·m·s: what the drive must deliver to
    bring the rest of the loop (belt and idle rollers, ``I = ½ m r²``) from rest to speed V. The
    belt on roller 1 (its arc plus half an element of each adjacent span, lumped) starts moving."""
    spans = [s for s in mesh.path.segments if s.kind == "free"]
    half = 0.5 * (spans[0].length / mesh.free_elements[0] + spans[-1].length / mesh.free_elements[-1])
    m_rest = rho_A * (mesh.length - mesh.path.segments[0].length - half)
    idle = sum(0.5 * m for m in masses[1:])  # I_j / r_j² = m_j / 2
    return radii[0] * V * (m_rest + idle)



CENTRES, RADII, MASSES = [[0.0, 0.0], [1.0, 0.0], [0.45, 0.45]], [0.08, 0.06, 0.10], [3.0, 2.0, 4.0]
# s: the convergence runs' time (36, 72, 144 steps: whole checkpoint chunks, the step compiles once);
# the 2D statics run as long (steady to 1e-8 after ~30 steps)
T_END = 0.72


def coarse_three_roller(name, n_eta=3, dt=0.02, n_xi=104, solver=None, **belt):
    def mutate(d):
        d["mesh"] = {"n_eta": n_eta, "n_xi": n_xi}
        d["time"] = {"dt_s": dt, "t_end_s": T_END}
        d.setdefault("belt", {}).update(belt)
        d.setdefault("solver", {}).update(solver or {})

    return compiled(scene_with(mutate, name))



def run_statics_1d(n_steps=400):
    """The two 1D tension scenes run for ``n_steps`` (the slowest start-up mode has decayed to
    1e-9 by 400): support loads, span tensions, drive torque and start-up impulse, each with its
    hand value (``*_hand``)."""
    out = {}
    for name in ("two-roller-1d-pretension", "two-roller-1d-tension"):
        sc = jb.load_scene(name)
        model, mesh, opts = compiled(sc)
        state, tr = jb.simulate(model, **opts.replace(n_steps=n_steps))
        reac = np.asarray(tr.roller_reaction)  # (steps, p, [dx, az]): support force / torque
        EA = E * sc.belt.area
        pre = sc.belt.length is not None
        T = EA * ((2 * 0.275 + 2 * math.pi * 0.05) / sc.belt.length - 1) if pre else 50.0  # 7.2405 N; 100 N / 2
        out[name] = dict(
            support=reac[-1, :, 0],
            support_hand=np.array([-2 * T, 2 * T] if pre else [-2 * T, 0.0]),  # tension roller: its residual
            span_tension=np.concatenate(span_strains(model, mesh, state.u)) * EA + (T if pre else 0.0),
            tension_hand=T, steady_torque=reac[-1, 0, 1], impulse=reac[:, 0, 1].sum() * opts.dt,
            impulse_hand=start_up_momentum(mesh, RHO * sc.belt.area, 0.5, [0.5, 0.5], [0.05, 0.05]))
    return out


def run_statics_2d():
    """``three-roller`` 1.6 mm short (pre-tension) and ``three-roller-tension``, coarsened: the
    support loads of every roller against ``−T (t_out − t_in)``, drive torque, start-up impulse."""
    t, L_path, _ = path_geometry(CENTRES, RADII)
    hub = np.array([t[i] - t[i - 1] for i in range(3)])
    out = {}
    for name, belt in (("three-roller", {"length_mm": 2830.0}), ("three-roller-tension", {})):
        model, mesh, opts = coarse_three_roller(name, **belt)
        # 36 steps; the tension roller (it moves during the start-up) 156, the run of test_model2d.py
        opts = opts if belt else opts.replace(n_steps=156)
        reac = np.asarray(jb.simulate(model, **opts)[1].roller_reaction)  # (steps, 3, 6)
        # pre-tension: T = E A ε₀; tension roller: the belt's pull on roller 2 balances the 200 N
        T = E * 0.4 * 0.3e-3 * (L_path / 2.830 - 1) if belt else 200.0 / -hub[1][0]  # 172.8 N; 115.15 N
        support_hand = -T * hub
        if not belt:
            support_hand[1, 0] = 0.0  # roller 2's x is dynamic: the residual of its equation
        out[name] = dict(
            path_length=mesh.length, path_length_hand=L_path, tension_hand=T, support=reac[-1, :, :2],
            support_hand=support_hand, steady_torque=reac[-1, 0, 5], impulse=reac[:, 0, 5].sum() * opts.dt,
            impulse_hand=start_up_momentum(mesh, RHO * 0.4 * 0.3e-3, 1.0, MASSES, RADII))
    return out


@pytest.fixture(scope="module")
def statics_1d():
    return run_statics_1d()


@pytest.fixture(scope="module")
def statics_2d():
    return run_statics_2d()


@pytest.mark.parametrize("name", ["two-roller-1d-pretension", "two-roller-1d-tension"])
def test_support_loads_span_tension_and_drive_torque_1d(statics_1d, name):
    r = statics_1d[name]
    np.testing.assert_allclose(r["support"], r["support_hand"], rtol=0, atol=1e-6 * r["tension_hand"])
    np.testing.assert_allclose(r["span_tension"], r["tension_hand"], rtol=1e-6)
    assert abs(r["steady_torque"]) < 1e-9  # N·m: no losses
    assert r["impulse"] == pytest.approx(r["impulse_hand"], rel=1e-5)


@pytest.mark.parametrize("name", ["three-roller", "three-roller-tension"])
def test_support_loads_and_drive_torque_2d(statics_2d, name):
    r = statics_2d[name]
    assert r["path_length"] == pytest.approx(r["path_length_hand"], rel=1e-12)
    np.testing.assert_allclose(r["support"], r["support_hand"], rtol=0, atol=1e-6 * r["tension_hand"])
    assert abs(r["steady_torque"]) < 1e-6  # N·m
    assert r["impulse"] == pytest.approx(r["impulse_hand"], rel=1e-5)


# ----------------------------------------------------------------------------- 3. lateral translation

LAT = dict(t=0.3e-3, w=0.05, L=1.0, d=1e-3, r=0.08)
XI = np.arange(0.1, 1.0, 0.2)  # tracers at the midpoints of five equal parts of each segment


def lateral_scene(eps0=0.0, span=40, arc=10, n_eta=5, dt=0.02, lateral_transport=False):
    """Two rollers (r = 80 mm) 1 m apart, a 50 × 0.3 mm belt at 1 m/s, roller 2 (idle) moved by
    d = 1 mm along its axis; ``eps0`` > 0 shortens the belt (pre-tension)."""
    L_loop = 2 * LAT["L"] + 2 * math.pi * LAT["r"]
    belt = {"length_mm": L_loop * 1e3 / (1 + eps0)} if eps0 else {}
    solver = {"lateral_transport": lateral_transport, **({} if eps0 else NO_TENSION)}
    sc = two_roller("2d", radius_mm=LAT["r"] * 1e3, width_mm=LAT["w"] * 1e3, thickness_mm=LAT["t"] * 1e3, arc=arc,
                    span=span, n_eta=n_eta, dt=dt, speed=1.0, second="idle", belt=belt, solver=solver)
    d = np.zeros((2, 3))
    d[1, 2] = LAT["d"]
    model, _, opts = compiled(sc)
    return jb.with_misalignment(model, translation=jnp.asarray(d)), opts


def beam_shapes(xi, eps0=0.0, kappa=5 / 6):
    """Lateral shape / d of a clamped-guided span (Timoshenko without tension, the tensioned
    Euler–Bernoulli beam with it) and its end shear force / d, N/m."""
    t, w, L = LAT["t"], LAT["w"], LAT["L"]
    EI = E * t * w**3 / 12
    if eps0 == 0.0:
        phi = (w / L) ** 2 * 2 * (1 + NU) / kappa  # 12 EI / (κ G A L²)
        return (3 * xi**2 - 2 * xi**3 + phi * xi) / (1 + phi), 12 * EI / (L**3 * (1 + phi))
    k = math.sqrt(E * eps0 * w * t / EI) * L  # K L
    ch, sh = math.cosh(k), math.sinh(k)
    A = np.array([[1, 0, 1, 0], [0, 1, 0, k], [1, 1, ch, sh], [0, 1, k * sh, k * ch]])
    a, b, c, e = np.linalg.solve(A, [0.0, 0.0, 1.0, 0.0])  # v/d = a + bξ + c cosh kξ + e sinh kξ
    # the shear |EI v''' − T v'| at ξ = 0 is (EI / L³)|e k³ − k² (b + e k)| = EI k² |b| / L³
    return a + b * xi + c * np.cosh(k * xi) + e * np.sinh(k * xi), EI * k**2 * abs(b) / L**3


def carried_rotation_shape(xi):
    """Steady running shape / d of span 1 when u (hence the rotation θ) is transported and v is
    not: ``v(0) = 0``, ``θ(0) = θ(L)`` of span 2, ``M(L) = 0``, ``v(L) = d``; span 2 is ``1 − v``."""
    return -3 * xi + 6 * xi**2 - 2 * xi**3


def run_lateral(eps0=0.0, n_steps=400, **mesh):
    """Lateral tracer values / d (roller 2 arc, span 1, span 2; 5 each) at rest and after
    ``n_steps`` of running, the history of roller 2's z support load (N) and its hand value."""
    model, opts = lateral_scene(eps0, **mesh)
    static = np.asarray(tracer_values(model, jb.initial_state(model).u)[1]) / LAT["d"]
    _, tr = jb.simulate(model, **opts.replace(n_steps=n_steps))
    v = np.asarray(tr.tracer_v) / LAT["d"]
    shape, shear = beam_shapes(XI, eps0)
    parts = lambda a: (a[..., 10:15], a[..., 5:10], a[..., 15:20])
    return dict(static=parts(static), running=parts(v[-1]), drift=np.abs(v[-1] - v[-26]).max(), shape_hand=shape,
                support=np.asarray(tr.roller_reaction)[:, 1, 2], support_hand=2 * shear * LAT["d"], history=v)


@pytest.fixture(scope="module")
def lateral():
    return {eps0: run_lateral(eps0) for eps0 in (0.0, 1e-3)}  # 400 steps: 3.2 loops at 1 m/s


@pytest.mark.parametrize("eps0", [0.0, 1e-3])
def test_lateral_translation_static_span_is_a_clamped_guided_beam(lateral, eps0):
    r = lateral[eps0]
    on_roller, span1, span2 = r["static"]
    np.testing.assert_allclose(on_roller, 1.0, rtol=1e-12)  # the belt on roller 2 moves by d
    np.testing.assert_allclose(span1, r["shape_hand"], rtol=0, atol=0.01)
    np.testing.assert_allclose(span2, r["shape_hand"][::-1], rtol=0, atol=0.01)
    assert r["support"][0] == pytest.approx(r["support_hand"], rel=0.02)  # first step: still the static field


def test_lateral_translation_running_default_variant_carries_the_rotation(lateral):
    r = lateral[0.0]
    on_roller, span1, span2 = r["running"]
    np.testing.assert_allclose(on_roller, 1.0, rtol=1e-12)
    np.testing.assert_allclose(span1, carried_rotation_shape(XI), rtol=0, atol=0.03)
    np.testing.assert_allclose(span2, 1 - carried_rotation_shape(XI), rtol=0, atol=0.03)
    assert r["drift"] < 1e-3  # steady (over the last 25 steps)
    assert r["support"][-1] == pytest.approx(r["support"][0], rel=0.01)  # same end shear: ξ³ term −2 d


def test_lateral_translation_with_lateral_transport_straightens_the_belt():
    r = run_lateral(lateral_transport=True, n_steps=1500)  # 12 loops
    assert np.ptp(r["history"][-1]) < 0.02  # straight: an axially translated cylinder does not steer
    assert abs(r["support"][-1]) < 0.01 * abs(r["support"][0])


# ----------------------------------------------------------------------------- 4. convergence orders

LAMBDA_CORNER = 0.742  # clamped–free right-angle corner, plane stress, ν = 0.34 (module docstring)


def corner_exponent(nu=NU):
    """Smallest root λ ∈ (0, 1) of ``κ² + 1 + 2κ cos(λπ) − 4λ² = 0``, κ = (3 − ν)/(1 + ν),
    by bisection."""
    kappa = (3 - nu) / (1 + nu)
    f = lambda lam: kappa**2 + 1 + 2 * kappa * math.cos(lam * math.pi) - 4 * lam**2
    lo, hi = 0.5, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(mid) > 0 else (lo, mid)
    return 0.5 * (lo + hi)


def t72_tracers(n_eta=3, dt=0.02, n_xi=104):
    """``(u, v)`` tracer displacements (m) of the coarsened ``three-roller-t72`` at ``T_END``."""
    model, _, opts = coarse_three_roller("three-roller-t72", n_eta=n_eta, dt=dt, n_xi=n_xi, solver=NO_TENSION)
    _, tr = jb.simulate(model, **opts)
    return np.asarray(tr.tracer_u)[-1], np.asarray(tr.tracer_v)[-1]


def observed_orders(runs):
    """Orders ``log2(|y₁ − y₂| / |y₂ − y₃|)`` for u and v from three runs refined by 2 each."""
    diff = lambda k, a, b: np.linalg.norm(runs[a][k] - runs[b][k])
    return tuple(math.log2(diff(k, 0, 1) / diff(k, 1, 2)) for k in (0, 1))


def test_corner_exponent():
    assert corner_exponent() == pytest.approx(LAMBDA_CORNER, abs=5e-4)


@pytest.fixture(scope="module")
def t72_runs():
    return {key: t72_tracers(*key) for key in ((3, 0.02), (3, 0.01), (3, 0.005), (5, 0.02), (9, 0.02))}


def test_convergence_order_in_dt_is_one(t72_runs):
    p_u, p_v = observed_orders([t72_runs[3, dt] for dt in (0.02, 0.01, 0.005)])
    assert abs(p_u - 1) < 0.1 and abs(p_v - 1) < 0.1


def test_convergence_order_in_n_eta_is_corner_limited(t72_runs):
    p_u, p_v = observed_orders([t72_runs[n, 0.02] for n in (3, 5, 9)])
    for p in (p_u, p_v):
        assert 2 * LAMBDA_CORNER - 0.35 < p < 2.1


def test_convergence_order_in_n_xi_at_fixed_courant_number():
    p_u, p_v = observed_orders([t72_tracers(3, 0.02 * 104 / n, n) for n in (208, 416, 832)])
    for p in (p_u, p_v):
        assert 0.8 < p < 1.8
