"""Belt walk on a skewed roller against the string limit, over the span parameter K L.

Two rollers (r = 80 mm, spans 1 m, V = 1 m/s, ``lateral_transport = true``), roller 2 rotated
about y (skew, in the plane of both spans) by α = 1 mrad; the walk rate is the slope of the
mean lateral tracer displacement over the second half of 20 s. Belt widths 10–800 mm and
pre-tension strains 0–2e-2 span K L = L √(T / EI) from 0 to ~25, with tension stiffening on and
off. References (docs/lateral.md): the string limit ``V α L_span / L_loop`` (normal entry at both
rollers and loop closure) and 2/3 of it (a moving beam). Writes ``results/lateral_theory.json``
and ``.png``.
"""

import numpy as np

import jaxbelt as jb
from _common import RESULTS, write

E, T_B, R, SPAN = 2.5e9, 0.3e-3, 0.08, 1.0
L_LOOP = 2 * SPAN + 2 * np.pi * R


def scene(w_mm, eps0, stiffening=True, n_eta=5, n_xi=100, dt=0.02, t_end=20.0):
    d = {"model": {"kind": "2d", "name": "two-roller-2d"},
         "belt": {"width_mm": w_mm, "thickness_mm": T_B * 1e3, "youngs_modulus_pa": E, "poisson_ratio": 0.34,
                  "density_kg_m3": 1420.0, **({"length_mm": L_LOOP * 1e3 * (1 - eps0)} if eps0 else {})},
         "roller": [{"name": f"roller {k + 1}", "center_mm": [1000.0 * k, 0.0], "radius_mm": R * 1e3,
                     "width_mm": max(450.0, w_mm + 50), "mass_kg": 3.0,
                     **({"role": "drive", "speed_m_s": 1.0} if k == 0 else {"role": "idle"})} for k in range(2)],
         "mesh": {"n_eta": n_eta, "n_xi": n_xi}, "time": {"dt_s": dt, "t_end_s": t_end},
         "solver": {"lateral_transport": True, "tension_stiffening": stiffening}}
    return jb.scene_from_dict(d)


def walk_rate(sc, alpha=1e-3, axis=1):
    import jax.numpy as jnp

    m = jb.compile_scene(sc)
    _, tr = jb.simulate(m.with_misalignment(rotation=jnp.zeros((2, 3)).at[1, axis].set(alpha)))
    t, v = np.asarray(tr.t), np.asarray(tr.tracer_v).mean(axis=1)
    n = len(t)
    return float(np.polyfit(t[n // 2:], v[n // 2:], 1)[0]) / alpha


def main():
    string = SPAN / L_LOOP
    rows = []
    for w in (10, 20, 50, 200, 800):
        for eps0 in (0.0, 1e-3, 5e-3, 2e-2):
            T = E * eps0 * w * 1e-3 * T_B
            EI = E * T_B * (w * 1e-3) ** 3 / 12
            for stiff in (True, False):
                r = walk_rate(scene(w, eps0, stiff))
                rows.append({"width_mm": w, "eps0": eps0, "tension_n": T, "KL": float(np.sqrt(T / EI) * SPAN),
                             "tension_stiffening": stiff, "rate_per_V_alpha": r, "ratio_to_string": r / string})
                print(f"w {w:4d} mm  ε0 {eps0:6.3g}  K L {rows[-1]['KL']:7.2f}  stiffening {stiff!s:5s}  "
                      f"walk {r:.4f} V α = {r / string:.3f} × string", flush=True)
    twist = walk_rate(scene(50, 5e-3), axis=0)
    print(f"twist (about x), w 50 mm, ε0 5e-3: {twist:.4f} V α; per-pass shift 2 r α V / L_loop = {2 * R / L_LOOP:.4f}")
    write("lateral_theory", {"string_rate_per_V_alpha": string, "rows": rows, "twist_rate_per_V_alpha": twist,
                             "twist_reference": 2 * R / L_LOOP})

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    for stiff, mk in ((True, "o"), (False, "x")):
        sel = [r for r in rows if r["tension_stiffening"] == stiff and r["KL"] > 0]
        ax.semilogx([r["KL"] for r in sel], [r["ratio_to_string"] for r in sel], mk,
                    label=f"jaxbelt, tension stiffening {'on' if stiff else 'off'}")
    ax.axhline(1.0, color="k", ls="--", label="string limit V α L_span / L_loop")
    ax.axhline(2 / 3, color="grey", ls=":", label="2/3 (moving beam, see docs/lateral.md)")
    ax.set_xlabel("span parameter K L")
    ax.set_ylabel("walk rate / string rate")
    ax.set_title("skewed roller: walk rate against K L (two rollers, spans 1 m)")
    ax.legend(fontsize=8)
    fig.savefig(RESULTS / "lateral_theory.png", dpi=120)


if __name__ == "__main__":
    main()
