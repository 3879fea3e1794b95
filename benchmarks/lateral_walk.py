"""What lateral transport changes: belt walk on a tilted roller (MODEL.md §3).

Roller 2 of ``three-roller`` (n_eta = 5 for speed) tilted about x by α; 20 s. Records the mean
lateral tracer displacement and its late-time rate with and without ``lateral_transport``, and
two kinematic references: the normal-entry rule ``V ψ(θ_in)`` (a belt enters perpendicular to
the roller axis) and the per-pass surface shift ``Δv_s = r α (sin θ_out − sin θ_in)`` spread over
one loop, ``Δv_s V / L``. Writes ``results/lateral_walk.json``/``.png``."""

import copy
import tomllib
from importlib import resources

import jax.numpy as jnp
import numpy as np

import jaxbelt as jb
from _common import RESULTS, write


def run(lateral, alpha, steps=1000):
    d = copy.deepcopy(tomllib.loads((resources.files("jaxbelt") / "scenes" / "three-roller.toml").read_text()))
    d["mesh"]["n_eta"] = 5
    d["solver"] = {"lateral_transport": lateral}
    sc = jb.scene_from_dict(d)
    mesh = jb.build_mesh(sc)
    m = jb.compile_scene(sc, mesh).with_misalignment(rotation=jnp.zeros((3, 3)).at[1, 0].set(alpha))
    _, tr = jb.simulate(m, n_steps=steps)
    t, v = np.asarray(tr.t), np.asarray(tr.tracer_v).mean(axis=1)
    rate = float(np.polyfit(t[steps // 2:], v[steps // 2:], 1)[0])
    seg = mesh.path.segments[2]
    th_in, th_out = seg.theta_in, seg.theta_in + seg.sense * seg.wrap
    r, s, V = mesh.path.radii[1], mesh.path.senses[1], 1.0
    normal_entry = V * s * alpha * np.cos(th_in)
    per_pass = r * alpha * (np.sin(th_out) - np.sin(th_in)) * V / mesh.length
    return t, v, {"lateral_transport": lateral, "alpha_rad": alpha, "walk_rate_mm_s": rate * 1e3,
                  "v_mean_final_mm": float(v[-1]) * 1e3, "normal_entry_rule_mm_s": normal_entry * 1e3,
                  "per_pass_shift_rule_mm_s": per_pass * 1e3}


def main():
    rows, curves = [], []
    for lateral in (False, True):
        for alpha in (2e-4, 4e-4):
            t, v, row = run(lateral, alpha)
            rows.append(row)
            curves.append((t, v, row))
            print(row, flush=True)
    write("lateral_walk", {"scene": "three-roller (n_eta = 5), roller 2 tilted about x", "rows": rows})

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.5, 3.8), constrained_layout=True)
    for t, v, row in curves:
        ax.plot(t, v * 1e3, label=f"α = {row['alpha_rad'] * 1e3:.1f} mrad, lateral transport {row['lateral_transport']}")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("mean lateral tracer displacement [mm]")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.savefig(RESULTS / "lateral_walk.png", dpi=120)


if __name__ == "__main__":
    main()
