"""Belt walk against theory: skewed and twisted rollers over the span parameter K L.

Two rollers (r = 80 mm, spans 1 m, V = 1 m/s, ``lateral_transport = true``), roller 2 skewed
(rotated about y, in the plane of both spans) by α = 1 mrad; the walk rate is the slope of the
mean lateral tracer displacement over the second half of the run. A tension sweep (w = 50 mm,
ε₀ 2.5e-5 … 2e-2) and a width sweep (ε₀ = 5e-3, w 5 … 800 mm) span K L = L √(T / EI) from 0.3 to
~100; every mesh resolves the boundary layer 1/K (element length ≤ 1/(2K), 6.25 mm at most,
n_η = 9 for belts wider than 100 mm) and Δt = 0.8 ℓ / V: the mesh-convergence rows show the walk
rate converging at second order in ℓ. Reference: the loop of moving
tensioned Timoshenko beams with the normal-entry law (:mod:`jaxbelt.lateral_theory`, derived in
docs/lateral.md), its Euler–Bernoulli limit, the string limit ``V α L_span / L_loop`` and the
beam limit (1/3 of it). Also: a twist (about x) against the per-pass shift ``2 r α V / L_loop``,
a mesh-convergence check, tension stiffening off, and the three-roller scene's tilt of roller 2
split into skew and twist per span. Writes ``results/lateral_theory.json`` and ``.png``.

``python benchmarks/lateral_theory.py [--quick | --shape | --coarse]`` (quick: three K L points,
coarse meshes; shape: only the steady span shape against the reference's,
``results/lateral_span_shape.json``; coarse: the skew and twist walk at K L = 4.9 on 8, 16 and
32 elements per roller arc, with the observed order of the walk rate,
``results/lateral_coarse_mesh.json``).
"""

import sys
import time

import numpy as np

import jaxbelt as jb
from jaxbelt import lateral_theory as th
from _common import RESULTS, write

E, NU, T_B, R, SPAN = 2.5e9, 0.34, 0.3e-3, 0.08, 1.0
L_LOOP = 2 * SPAN + 2 * np.pi * R
STRING = -SPAN / L_LOOP  # V α L_span / L_loop, signed: roller 2 skewed by +α walks the belt towards −z


def span_parameter(w, eps0):
    """K L of the two-roller scene with belt width ``w`` (m) and pre-tension strain ``eps0``."""
    return float(np.sqrt(12.0 * eps0) / w * SPAN)


def scene(w_mm, eps0, stiffening=True, n_eta=None, n_xi=None, dt=None, t_end=20.0):
    w = w_mm * 1e-3
    kl = span_parameter(w, eps0)
    ell = min(L_LOOP / 400, SPAN / (2.0 * kl)) if kl > 0 else L_LOOP / 400
    n_xi = n_xi or int(np.ceil(L_LOOP / ell / 4) * 4)
    n_eta = n_eta or (9 if w_mm > 100 else 5)
    dt = dt or round(0.8 * L_LOOP / n_xi, 5)
    d = {"model": {"kind": "2d", "name": "two-roller-2d"},
         "belt": {"width_mm": w_mm, "thickness_mm": T_B * 1e3, "youngs_modulus_pa": E, "poisson_ratio": NU,
                  "density_kg_m3": 1420.0, **({"length_mm": L_LOOP * 1e3 / (1 + eps0)} if eps0 else {})},
         "roller": [{"name": f"roller {k + 1}", "center_mm": [1000.0 * k, 0.0], "radius_mm": R * 1e3,
                     "width_mm": max(450.0, w_mm + 50), "mass_kg": 3.0,
                     **({"role": "drive", "speed_m_s": 1.0} if k == 0 else {"role": "idle"})} for k in range(2)],
         "mesh": {"n_eta": n_eta, "n_xi": n_xi}, "time": {"dt_s": dt, "t_end_s": t_end},
         "solver": {"lateral_transport": True, "tension_stiffening": stiffening, "linear_solver": "reuse"}}
    return jb.scene_from_dict(d)


def simulated_walk(sc, rotation):
    """Walk rate (m/s) of a scene with roller rotations ``rotation`` (p, 3): slope of the mean
    lateral tracer displacement over the second half, and over the last quarter (settling)."""
    import jax.numpy as jnp

    m = jb.with_misalignment(jb.build_model(sc), rotation=jnp.asarray(rotation))
    _, tr = jb.simulate(m, **jb.RunOptions.from_scene(sc))
    t, v = np.asarray(tr.t), np.asarray(tr.tracer_v).mean(axis=1)
    n = len(t)
    return float(np.polyfit(t[n // 2:], v[n // 2:], 1)[0]), float(np.polyfit(t[3 * n // 4:], v[3 * n // 4:], 1)[0])


def references(sc, rotation):
    return {"timoshenko": th.scene_walk_rate(sc, rotation),
            "euler_bernoulli": th.scene_walk_rate(sc, rotation, shear=False)}


def skew_row(w_mm, eps0, alpha=1e-3, **kw):
    sc = scene(w_mm, eps0, **kw)
    rot = np.zeros((2, 3))
    rot[1, 1] = alpha
    t0 = time.perf_counter()
    c, c_late = simulated_walk(sc, rot)
    ref = references(sc, rot)
    row = {"width_mm": w_mm, "eps0": eps0, "KL": span_parameter(w_mm * 1e-3, eps0),
           "n_xi": sc.mesh.n_xi, "n_eta": sc.mesh.n_eta, "dt_s": sc.time.dt,
           "tension_stiffening": sc.solver.tension_stiffening,
           "model_per_string": c / (alpha * STRING), "model_late_per_string": c_late / (alpha * STRING),
           "timoshenko_per_string": ref["timoshenko"] / (alpha * STRING),
           "euler_bernoulli_per_string": ref["euler_bernoulli"] / (alpha * STRING),
           "wall_s": time.perf_counter() - t0}
    row["error_vs_timoshenko"] = row["model_per_string"] / row["timoshenko_per_string"] - 1.0
    print(f"w {w_mm:5.0f} mm  ε0 {eps0:7.2g}  K L {row['KL']:7.2f}  n_xi {row['n_xi']:4d} n_eta {row['n_eta']}  "
          f"model {row['model_per_string']:+.4f}  Timoshenko {row['timoshenko_per_string']:+.4f}  "
          f"EB {row['euler_bernoulli_per_string']:+.4f}  error {100 * row['error_vs_timoshenko']:+.2f} %  "
          f"({row['wall_s']:.0f} s)", flush=True)
    return row


def three_roller(alpha=2e-4, n_eta=9, n_xi=208, dt=0.01, t_end=20.0):
    """The three-roller scene's roller 2 tilted about x: simulated walk vs the reference, and the
    tilt split into the skew its two spans see and the twist's per-pass shift."""
    import copy
    import tomllib
    from importlib import resources

    d = copy.deepcopy(tomllib.loads((resources.files("jaxbelt") / "scenes" / "three-roller.toml").read_text()))
    d["mesh"].update(n_eta=n_eta, n_xi=n_xi)
    d["time"].update(dt_s=dt, t_end_s=t_end)
    d["solver"] = {"lateral_transport": True, "linear_solver": "reuse"}
    sc = jb.scene_from_dict(d)
    rot = np.zeros((3, 3))
    rot[1, 0] = alpha
    c, c_late = simulated_walk(sc, rot)
    geom, _ = th.scene_geometry(sc)
    split = th.steering_split(geom, rot)[1]
    ref = th.scene_walk_rate(sc, rot, tension=0.0)
    row = {"alpha_rad": alpha, "n_eta": n_eta, "n_xi": n_xi, "dt_s": dt,
           "model_mm_s": c * 1e3, "model_late_mm_s": c_late * 1e3, "timoshenko_mm_s": ref * 1e3,
           "euler_bernoulli_mm_s": th.scene_walk_rate(sc, rot, tension=0.0, shear=False) * 1e3,
           "roller_2_skew_in_mrad": split["skew_in_rad"] * 1e3, "roller_2_skew_out_mrad": split["skew_out_rad"] * 1e3,
           "roller_2_per_pass_shift_um": split["per_pass_shift_m"] * 1e6,
           "per_pass_shift_rate_mm_s": split["per_pass_shift_m"] * 1e3 / sum(s.length for s in jb.build_mesh(sc).path.segments)}
    row["error_vs_timoshenko"] = row["model_mm_s"] / row["timoshenko_mm_s"] - 1.0
    print("three-roller:", row, flush=True)
    return row


def span_shape(w_mm=50, eps0=5e-3, alpha=1e-3, n_xis=(200, 400)):
    """Steady lateral span shape: the centre-line tracers of both spans at the end of the run
    (walk offset removed) against the reference's Timoshenko span shape, on two meshes."""
    import jax.numpy as jnp

    rows = []
    for n_xi in n_xis:
        sc = scene(w_mm, eps0, n_xi=n_xi, dt=round(0.8 * L_LOOP / n_xi, 5), t_end=16.0)
        mesh = jb.build_mesh(sc)
        rot = np.zeros((2, 3))
        rot[1, 1] = alpha
        m = jb.with_misalignment(jb.build_model(sc, mesh), rotation=jnp.asarray(rot))
        _, tr = jb.simulate(m, **jb.RunOptions.from_scene(sc))
        v = np.asarray(tr.tracer_v[-1])
        EI, kGA = th.belt_section(w_mm * 1e-3, T_B, E, NU)
        _, shape = th.beam_walk_rate(th.scene_geometry(sc)[0], rot, E * eps0 * w_mm * 1e-3 * T_B, EI, kGA,
                                return_shape=True)
        xs, mv, rv = th.span_tracer_shapes(mesh, v, shape)
        rows.append({"n_xi": n_xi, "x_m": xs.tolist(), "model_mm": (mv * 1e3).tolist(), "reference_mm": (rv * 1e3).tolist(),
                     "range_mm": float(np.ptp(rv) * 1e3), "max_error_over_range": float(np.max(np.abs(mv - rv)) / np.ptp(rv))})
        print(f"span shape n_xi {n_xi}: range {rows[-1]['range_mm']:.3f} mm, max error "
              f"{100 * rows[-1]['max_error_over_range']:.2f} % of it", flush=True)
    return rows


def coarse_meshes(per_arc=(8, 16, 32), w_mm=50, eps0=5e-3, alpha=1e-3):
    """Skew and twist walk on coarse meshes (``per_arc`` elements on each roller arc, Δt = 0.8 ℓ / V,
    n_η = 5) against the references; the observed order of the walk rate from the three meshes."""
    arc = np.pi * R
    out = {"per_arc": list(per_arc), "KL": span_parameter(w_mm * 1e-3, eps0), "skew": [], "twist": []}
    for k in per_arc:
        n_xi = int(round(L_LOOP / (arc / k)))
        sc = scene(w_mm, eps0, n_xi=n_xi, dt=round(0.8 * L_LOOP / n_xi, 5))
        for kind, axis in (("skew", 1), ("twist", 0)):
            rot = np.zeros((2, 3))
            rot[1, axis] = alpha
            c, _ = simulated_walk(sc, rot)
            exact = references(sc, rot)["timoshenko"]  # the twist's: the per-pass shift 2 r α V / L_loop
            row = {"per_arc": k, "n_xi": n_xi, "dt_s": sc.time.dt, "model_m_s": c, "reference_m_s": exact,
                   "error": c / exact - 1.0}
            out[kind].append(row)
            print(f"{kind:5s} {k:3d} elements an arc (n_xi {n_xi}): walk {c * 1e6:+.4f} µm/s against "
                  f"{exact * 1e6:+.4f}: {100 * row['error']:+.3f} %", flush=True)
    for kind in ("skew", "twist"):
        w = [r["model_m_s"] for r in out[kind]]
        d1, d2 = abs(w[0] - w[1]), abs(w[1] - w[2])
        out[f"{kind}_observed_order"] = float(np.log2(d1 / d2)) if d1 > 0 and d2 > 0 else None
        print(f"{kind}: observed order of the walk rate {out[f'{kind}_observed_order']}", flush=True)
    write("lateral_coarse_mesh", out)


def main(quick=False):
    if quick:
        cases = [(50, 2.5e-5), (50, 5e-3), (10, 2e-2)]
    else:
        tension = [(50, e) for e in (2.5e-5, 1e-4, 1e-3, 5e-3, 2e-2)]
        width = [(w, 5e-3) for w in (5, 10, 20, 200, 800)]
        cases = sorted(tension + width + [(5, 2e-2)], key=lambda c: span_parameter(c[0] * 1e-3, c[1]))
    rows = [skew_row(w, e, **({"n_xi": 100, "dt": 0.02} if quick else {})) for w, e in cases]
    off = [skew_row(w, e, stiffening=False, **({"n_xi": 100, "dt": 0.02} if quick else {}))
           for w, e in ([(50, 5e-3)] if quick else [(50, 1e-4), (50, 5e-3), (10, 2e-2)])]
    conv = [] if quick else [skew_row(50, 5e-3, n_xi=n, dt=round(0.8 * L_LOOP / n, 5)) for n in (100, 200, 400)]
    sc = scene(50, 5e-3, **({"n_xi": 100, "dt": 0.02} if quick else {}))
    rot = np.zeros((2, 3))
    rot[1, 0] = 1e-3
    twist, _ = simulated_walk(sc, rot)
    twist_row = {"model_per_V_alpha": twist / 1e-3, "per_pass_shift_per_V_alpha": 2 * R / L_LOOP,
                 "timoshenko_per_V_alpha": references(sc, rot)["timoshenko"] / 1e-3}
    print("twist:", twist_row, flush=True)
    three = three_roller(**({"n_eta": 5, "n_xi": 104, "dt": 0.02} if quick else {}))
    sc_str = scene(50, 5e-3, n_xi=100, dt=0.02)
    rot_y = np.zeros((2, 3))
    rot_y[1, 1] = 1e-3
    string_check = th.scene_walk_rate(sc_str, rot_y, tension=1e12, shear=False) / 1e-3
    print(f"string limit: formula {STRING:+.5f} V α, reference at K L = {np.sqrt(1e12 / th.belt_section(0.05, T_B, E, NU)[0]):.0f}: {string_check:+.5f} V α")
    write("lateral_theory_quick" if quick else "lateral_theory",
          {"string_rate_per_V_alpha": STRING, "string_limit_of_reference": string_check, "skew": rows, "skew_tension_stiffening_off": off,
           "skew_mesh_convergence": conv, "twist": twist_row, "three_roller_tilt": three})
    plot(rows, off, "lateral_theory_quick" if quick else "lateral_theory")


def plot(rows, off, name):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kl = np.logspace(-1.5, 2.3, 200)
    w = 0.05
    eps = (kl * w / SPAN) ** 2 / 12.0
    geom_sc = scene(50, 5e-3, n_xi=100, dt=0.02)
    rot = np.zeros((2, 3))
    rot[1, 1] = 1.0
    EI, kGA = th.belt_section(w, T_B, E, NU)
    geom, _ = th.scene_geometry(geom_sc)
    eb = [th.beam_walk_rate(geom, rot, E * e * w * T_B, EI, np.inf) / STRING for e in eps]
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    ax.semilogx(kl, np.array(eb), "k-", lw=1, label="theory: Euler–Bernoulli beam loop (w = 50 mm)")
    ax.semilogx([r["KL"] for r in rows], [r["timoshenko_per_string"] for r in rows], "s", mfc="none", color="C1",
                ms=9, label="theory: Timoshenko beam loop (each case)")
    ax.semilogx([r["KL"] for r in rows], [r["model_per_string"] for r in rows], "o", color="C0",
                label="jaxbelt 2D (widths 5–800 mm, ε₀ 2.5e-5–2e-2)")
    ax.semilogx([r["KL"] for r in off], [r["model_per_string"] for r in off], "x", color="C3",
                label="jaxbelt 2D, tension stiffening off")
    ax.axhline(1.0, color="grey", ls="--", lw=0.8, label="string limit V α L_span / L_loop")
    ax.axhline(1 / 3, color="grey", ls=":", lw=0.8, label="beam limit (1/3)")
    ax.set_xlabel("span parameter K L = L √(T / EI)")
    ax.set_ylabel("walk rate / string rate")
    ax.set_title("skewed roller: belt walk against K L (two rollers, spans 1 m, α = 1 mrad)")
    ax.legend(fontsize=7.5)
    fig.savefig(RESULTS / f"{name}.png", dpi=120)
    print(f"wrote {RESULTS / (name + '.png')}")


if __name__ == "__main__":
    if "--coarse" in sys.argv:
        coarse_meshes()
    elif "--shape" in sys.argv:  # the span-shape comparison alone
        write("lateral_span_shape", {"scene": "two rollers, w = 50 mm, eps0 = 5e-3, K L = 4.9, roller 2 skewed 1 mrad",
                                     "rows": span_shape()})
    else:
        main(quick="--quick" in sys.argv)
