"""The speed/accuracy trade as the program makes it: ``--accuracy-um`` on the default 2D scene,
beside the grids around it.

Scene ``three-roller-t72`` (the source's §7.2 setup with its Table 7.2 misalignments) over
``T`` = 2 s; the error is taken over the last 20 % (1.6–2 s, the window a design metric reads),
on the lateral and the longitudinal tracer displacement both. Candidates: the scene's grid
refined by 1/2, 1 and 2 across, 1 and 2 along the belt and 1, 2 and 4 in Δt (those the CFL
condition admits); each run's true error is taken against the scene refined 4× in every
direction, and its time is the run's wall time (compilation apart). For each accuracy asked,
:func:`jaxbelt.accuracy.choose_grid` — the code behind ``--accuracy-um`` — picks a grid; its
estimate, true error and cost are recorded and marked in the picture. The table
``results/accuracy_trade.md`` ("if you need X µm, use …") is written from those choices, so the
table and the program's choice are the same thing.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/accuracy_trade.py``. Writes
``results/accuracy_trade.json``, ``.png`` and ``.md``.
"""

import dataclasses
import itertools
import time

import numpy as np
from _common import RESULTS, write

import jaxbelt as jb
from jaxbelt.accuracy import admissible, at_times, choose_grid, refine, scene_grid, tracer_run

SCENE, T_END, WINDOW = "three-roller-t72", 2.0, 0.2
TARGETS_UM = (40.0, 20.0, 10.0)


def window_error_um(run, scene, truth, truth_scene, t_from):
    """Largest |u − u_truth| and |v − v_truth| over the window, µm."""
    k = int(round(scene.time.t_end / scene.time.dt))
    u, v = at_times(run, scene.time.dt, scene.time.dt, k, t_from)
    tu, tv = at_times(truth, truth_scene.time.dt, scene.time.dt, k, t_from)
    return float(np.max(np.abs(u - tu)) * 1e6), float(np.max(np.abs(v - tv)) * 1e6)


def main():
    base = jb.load_scene(SCENE)
    scene = base.replace(time=dataclasses.replace(base.time, t_end=T_END))
    t_from = (1 - WINDOW) * T_END
    t0 = time.perf_counter()
    truth_scene = refine(scene, n_xi=4.0, n_eta=4.0, dt=4.0)
    truth = tracer_run(truth_scene)
    print(f"truth {scene_grid(truth_scene)}: {truth.run_s:.1f} s", flush=True)
    rows = []
    for fe, fx, ft in itertools.product((0.5, 1.0, 2.0), (1.0, 2.0), (1.0, 2.0, 4.0)):
        sc = refine(scene, n_xi=fx, n_eta=fe, dt=ft)
        if not admissible(sc):
            continue
        r = tracer_run(sc)
        eu, ev = window_error_um(r, sc, truth, truth_scene, t_from)
        g = scene_grid(sc)
        rows.append(dict(n_xi=g.n_xi, n_eta=g.n_eta, dt_s=g.dt, run_s=r.run_s, longitudinal_um=eu, lateral_um=ev))
        print(f"grid {g.n_eta}×{g.n_xi} dt {g.dt:g}: {r.run_s:.3f} s, u {eu:.3g} µm, v {ev:.3g} µm", flush=True)
    chosen = []
    for x in TARGETS_UM:
        c = choose_grid(scene, x, t_from=t_from)
        r = tracer_run(c.scene)
        eu, ev = window_error_um(r, c.scene, truth, truth_scene, t_from)
        chosen.append(dict(**{k: v for k, v in c.to_dict().items() if k != "discretisation_error_um"},
                           true_longitudinal_um=eu, true_lateral_um=ev, run_s=r.run_s))
        print(f"need {x:g} µm: n_eta {c.grid.n_eta} n_xi {c.grid.n_xi} dt {c.grid.dt:g}, estimate {c.estimate_um:.3g} "
              f"µm, true u {eu:.3g} v {ev:.3g} µm, {r.run_s:.3f} s", flush=True)
    out = dict(scene=SCENE, t_end_s=T_END, window_s=[t_from, T_END], truth=dataclasses.asdict(scene_grid(truth_scene)),
               candidates=rows, chosen=chosen, wall_s=time.perf_counter() - t0)
    write("accuracy_trade", out)
    _table(out)
    _plot(out)


def _table(out):
    lines = [f"The grid `--accuracy-um` chooses on `{out['scene']}` over {out['t_end_s']:g} s (error over "
             f"{out['window_s'][0]:g}–{out['window_s'][1]:g} s, lateral and longitudinal; truth: the scene refined 4× "
             "in every direction):", "",
             "| if you need (µm) | use (n_η × n_ξ, Δt) | estimate (µm) | true error u / v (µm) | it costs (s a run) |",
             "|---|---|---|---|---|"]
    for c in out["chosen"]:
        lines.append(f"| ≤ {c['accuracy_um']:g} | {c['n_eta']} × {c['n_xi']}, Δt {c['dt_s']:g} s | {c['estimate_um']:.3g} | "
                     f"{c['true_longitudinal_um']:.3g} / {c['true_lateral_um']:.3g} | {c['run_s']:.3g} |")
    (RESULTS / "accuracy_trade.md").write_text("\n".join(lines) + "\n")


def _plot(out):
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 5))
    c = out["candidates"]
    err = [max(r["longitudinal_um"], r["lateral_um"]) for r in c]
    ax.loglog([r["run_s"] for r in c], err, "o", color="0.6", label="grids around the scene's")
    for r, e in zip(c, err):
        ax.annotate(f"{r['n_eta']}×{r['n_xi']}, {r['dt_s']:g}", (r["run_s"], e), fontsize=6, color="0.4")
    for ch in out["chosen"]:
        e = max(ch["true_longitudinal_um"], ch["true_lateral_um"])
        ax.loglog(ch["run_s"], e, "*", ms=14, label=f"chosen for {ch['accuracy_um']:g} µm")
        ax.axhline(ch["accuracy_um"], lw=0.6, ls=":", color=ax.lines[-1].get_color())
    ax.set_xlabel("run time, s (compilation apart)")
    ax.set_ylabel("true error over the window (max of u, v), µm")
    ax.set_title(f"{out['scene']}: error against cost, and the grids --accuracy-um chooses")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / "accuracy_trade.png", dpi=120)


if __name__ == "__main__":
    main()
