"""The speed/accuracy trade on the default scene, as a Pareto plot: tracer error against wall time
and against memory, for every way a user can buy speed.

Scene ``three-roller-t72`` (the source's §7.2 setup with the Table 7.2 misalignments: roller 1
3 mm along y, roller 2 0.4 mrad about x, roller 3 −1 mm along x), over its first ``T`` seconds
(20 s; ``--quick``: 4 s). Candidates:

* **grid** (n_η × n_ξ from 2 × 104 to 36 × 208, Δt = 0.02 s, or 0.01 s where the finer grid's CFL
  limit asks for it), reuse solver;
* **Δt** 0.02 / 0.01 / 0.005 s on the default 18 × 104 grid;
* **solver**: exact structured, reuse with 0 / 1 / 2 refinement iterations;
* **integrator**: naive (full DAE), direct, eliminated (algebraic unknowns substituted) — the
  first and last solve a dense system per step in 2D and are timed over 10 steps, projected;
* **precision**: float32 (its own process, without ``jax_enable_x64``) against float64;
* **reduced models** at several ranks: DMD of the post-transport states (trained on the first
  400 steps, 50 in quick mode, predicting the rest) and the fully reduced POD step
  (:mod:`jaxbelt.rom.pod_step`, trained on the same steps, all ranks from one projection).

**Truth**: the finest run, 36 × 208 at Δt = 0.005 s (N = 14994, 4× the default's unknowns and
steps), reuse solver with 2 refinement iterations. How converged it is: the lateral tracer
deviation changes by ~0.03 µm from 18 to 36 across the width at that Δt, and not at all (to 1e-10 µm)
from Δt 0.01 to 0.005 s at 36 × 208 — the lateral error figures below 0.05 µm are at the
truth's own resolution. The longitudinal tracer displacement is dominated by the drive's start-up
transient, which Backward Euler damps in proportion to Δt: it still moves by ~50 µm from Δt 0.01 to
0.005 s, so longitudinal errors are reported at the final time only (the quasi-static state),
and against the same truth.

Errors (µm): ``lateral_max_um`` — max over the tracers and the output times (every 0.02 s) of
``|v − v_truth|``, the design quantity; ``longitudinal_final_um`` — max over the tracers of
``|u − u_truth|`` at ``T``. Time: wall seconds of the run (compilation apart; for a reduced model,
snapshots + fit + online run), best of ``repeat``. Memory: XLA's memory analysis of the compiled
run (arguments + outputs + temporaries; for a reduced model the largest of its snapshot run and
its online run).
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from ..build import build_model
from ..integrators import DirectBackwardEuler, KeptInterior, Reuse, make_solver
from ..rom import collect_first_order, fit_dmd, fit_reduced_pod_ranks, parameters, tracer_operator
from ..scene import TimeSpec, load_scene
from ..state import initial_state
from ..run_checks import check_finite
from ..timeloop import RunOptions, simulate
from .timing import clock, compile_run, compiled_bytes, write_json

SCENE = "three-roller-t72"
OUT_DT = 0.02  # s, the common output grid of all candidates


def _log(msg):
    print(msg, file=sys.stderr, flush=True)


def _scene(n_eta, n_xi, dt, t_end):
    base = load_scene(SCENE)
    return base.replace(mesh=dataclasses.replace(base.mesh, n_eta=n_eta, n_xi=n_xi), time=TimeSpec(dt=dt, t_end=t_end))


def _built(n_eta, n_xi, dt, t_end):
    """``(model, n_steps, dt)`` of the default scene on another grid, time step and horizon."""
    sc = _scene(n_eta, n_xi, dt, t_end)
    opts = RunOptions.from_scene(sc)
    return build_model(sc), opts.n_steps, opts.dt


def _full_run(model, solver, n_steps, dt, repeat):
    """``(time_s, compile_s, bytes, tracer_u, tracer_v)`` on the common output grid."""
    run, comp, nbytes = compile_run(model, solver, n_steps=n_steps, dt=dt)
    best, out = np.inf, None
    for _ in range(repeat):
        t, out = clock(run, model, dt)
        best = min(best, t)
    tr = out[1]
    check_finite(tr, dt)
    k = int(round(OUT_DT / dt))
    return best, comp, nbytes, np.asarray(tr.tracer_u)[k - 1::k], np.asarray(tr.tracer_v)[k - 1::k]


_F32_CHILD = r"""
import sys, numpy as np
import jaxbelt as jb
from jaxbelt.bench.pareto import _built, _full_run
m, n, dt = _built(18, 104, 0.02, float(sys.argv[1]))
t, comp, nbytes, u, v = _full_run(m, jb.DirectBackwardEuler(jb.Reuse()), n, dt, int(sys.argv[2]))
np.savez(sys.argv[3], t=t, comp=comp, nbytes=-1 if nbytes is None else nbytes, u=u.astype(np.float64),
         v=v.astype(np.float64), dtype=str(u.dtype))
"""


def _float32_run(t_end, repeat):
    """The reuse run on the default grid in float32, in its own process (JAX's precision is
    process-wide)."""
    with tempfile.TemporaryDirectory() as d:
        out = str(Path(d) / "f32.npz")
        env = {**os.environ, "JAX_ENABLE_X64": "0"}
        r = subprocess.run([sys.executable, "-c", _F32_CHILD, str(t_end), str(repeat), out], env=env,
                           capture_output=True, text=True)
        if r.returncode:
            raise RuntimeError("float32 child failed: " + " | ".join(r.stderr.strip().splitlines()[-3:]))
        z = np.load(out)
        if str(z["dtype"]) != "float32":
            raise RuntimeError(f"float32 child ran in {z['dtype']}")
        return float(z["t"]), float(z["comp"]), (int(z["nbytes"]) if int(z["nbytes"]) >= 0 else None), z["u"], z["v"]


def _errors(u, v, truth):
    tu, tv = truth
    return {"lateral_max_um": float(np.abs(v - tv).max() * 1e6),
            "longitudinal_final_um": float(np.abs(u[-1] - tu[-1]).max() * 1e6),
            "longitudinal_max_um": float(np.abs(u - tu).max() * 1e6)}


def _reduced_models(model, n_steps, dt, n_train, dmd_ranks, pod_ranks, repeat, truth):
    """DMD and fully reduced POD rows: trained on the first ``n_train`` steps, predicting the rest."""
    reuse = DirectBackwardEuler(Reuse())
    n = int(n_steps)
    k = int(round(OUT_DT / dt))
    s0 = initial_state(model)
    snap = eqx.filter_jit(lambda m, t: collect_first_order(m, RunOptions(reuse, n_train, t))).lower(model, jnp.asarray(dt)).compile()
    snap_bytes = compiled_bytes(snap)
    snap(model, jnp.asarray(dt))
    t_snap = min(clock(snap, model, jnp.asarray(dt))[0] for _ in range(repeat))
    _, Zp, Zq = snap(model, jnp.asarray(dt))
    # the training window's own tracers (the full model's, as the reduced run replays them)
    C, Cz = tracer_operator(model), tracer_operator(model, "z")
    N = model.n_unknowns
    train_u = np.asarray(Zq[:N, 1:].T @ C.T)
    train_v = np.asarray(Zq[:N, 1:].T @ Cz.T)
    obs = jnp.concatenate([jnp.concatenate([C, jnp.zeros_like(C)], 1), jnp.concatenate([Cz, jnp.zeros_like(C)], 1)])
    rows = {}

    def fit_time(fn):  # compilation apart, as everywhere here: a warm call first, then the best of `repeat`
        fn()
        return min(clock(fn)[0] for _ in range(repeat)), fn()

    for r in dmd_ranks:
        t_fit, dmd = fit_time(lambda: fit_dmd(Zq, rank=r).stable())
        pred = jax.jit(lambda z: dmd.predict(z, n - n_train, observe=obs))
        comp = pred.lower(Zq[:, -1]).compile()
        pred(Zq[:, -1])
        t_on = min(clock(pred, Zq[:, -1])[0] for _ in range(repeat))
        p = np.asarray(pred(Zq[:, -1]))
        ntr = C.shape[0]
        u = np.concatenate([train_u, p[:, :ntr]])[k - 1::k]
        v = np.concatenate([train_v, p[:, ntr:]])[k - 1::k]
        label = "full rank" if r is None else r
        rows[f"DMD r={label}"] = dict(family="reduced: DMD", rank=int(dmd.eigs.size), time_s=t_snap + t_fit + t_on,
                                     offline_s=t_snap + t_fit, online_s=t_on,
                                     bytes=max(x for x in (snap_bytes, compiled_bytes(comp)) if x is not None),
                                     train_steps=n_train, **_errors(u, v, truth))
        _log(f"  DMD r={label}: {rows[f'DMD r={label}']['lateral_max_um']:.3g} µm lateral")
    Z = jnp.concatenate([Zp, Zq], axis=1)
    t_fit, roms = fit_time(lambda: fit_reduced_pod_ranks(model, Z, pod_ranks, dt=dt, solver=reuse))
    mu = parameters(model)
    for r, rom in roms.items():
        xi0 = rom.project(model, s0)
        run = jax.jit(lambda x, rom=rom: rom.run(x, mu, n))
        comp = run.lower(xi0).compile()
        run(xi0)
        t_on = min(clock(run, xi0)[0] for _ in range(repeat))
        out = run(xi0)
        u, v = np.asarray(out.tracer_u)[k - 1::k], np.asarray(out.tracer_v)[k - 1::k]
        rows[f"POD r={r}"] = dict(family="reduced: POD", rank=r, time_s=t_snap + t_fit + t_on,
                                  offline_s=t_snap + t_fit, online_s=t_on, fit_all_ranks_s=t_fit,
                                  bytes=max(x for x in (snap_bytes, compiled_bytes(comp)) if x is not None),
                                  train_steps=n_train, **_errors(u, v, truth))
        _log(f"  POD r={r}: {rows[f'POD r={r}']['lateral_max_um']:.3g} µm lateral")
    return rows


def _integrators(model, dt, direct_row, T, n_short=(("naive", 2), ("eliminated", 5))):
    """The naive (full DAE) and eliminated integrators. Both solve a dense system per step in 2D
    (17 s and 1.8 s per step at N = 3762 on 2 cores), so they are run for 2 and 5 steps only (quick: 1, 2):
    their time over ``T`` is projected from the measured per-step time (``projected: true``),
    their error bounded by the direct integrator's error plus their measured deviation from it
    over those steps (the three are the same discrete equations; they differ by round-off)."""
    rows = {}
    for name, n_short in n_short:
        ref = simulate(model, make_solver("direct"), n_steps=n_short, dt=dt)[1]
        run, _, nbytes = compile_run(model, make_solver(name), n_steps=n_short, dt=dt)
        t, out = clock(run, model, dt)
        tr = out[1]
        dev = float(max(np.abs(np.asarray(tr.tracer_u) - np.asarray(ref.tracer_u)).max(),
                        np.abs(np.asarray(tr.tracer_v) - np.asarray(ref.tracer_v)).max()) * 1e6)
        steps = int(round(T / dt))
        rows[f"integrator {name}"] = dict(
            family="integrator", n_unknowns=int(model.n_unknowns), dt=float(dt), time_s=t / n_short * steps,
            projected=True, measured_steps=n_short, ms_per_step=1e3 * t / n_short, bytes=nbytes,
            deviation_from_direct_um=dev, lateral_max_um=direct_row["lateral_max_um"] + dev,
            longitudinal_final_um=direct_row["longitudinal_final_um"] + dev,
            longitudinal_max_um=direct_row["longitudinal_max_um"] + dev)
        _log(f"  integrator {name}: {1e3 * t / n_short:.0f} ms per step, deviation from direct {dev:.2g} µm")
    return rows


def run(out_dir: Path, quick: bool = False) -> dict:
    """The whole trade; writes ``pareto[_quick].json``, ``.png`` and ``.md`` (the Pareto front) into ``out_dir``."""
    t_start = time.perf_counter()
    T = 4.0 if quick else 20.0
    repeat = 2 if quick else 3
    _log(f"pareto on {SCENE}, T = {T:g} s ({'quick' if quick else 'full'})")
    truth_m, truth_n, truth_dt = _built(36, 208, 0.005, T)
    t_truth, _, _, tu, tv = _full_run(truth_m, DirectBackwardEuler(Reuse(refine=2)), truth_n, truth_dt, 1)
    truth = (tu, tv)
    _log(f"  truth N = {truth_m.n_unknowns}: {t_truth:.1f} s")
    rows = {}

    def add(name, family, built, solver, **extra):
        model, n_steps, dt = built
        t, comp, nbytes, u, v = _full_run(model, solver, n_steps, dt, repeat)
        rows[name] = dict(family=family, n_unknowns=int(model.n_unknowns), dt=float(dt), time_s=t,
                          compile_s=comp, bytes=nbytes, **extra, **_errors(u, v, truth))
        _log(f"  {name}: {t:.2f} s, {rows[name]['lateral_max_um']:.3g} µm lateral, "
             f"{rows[name]['longitudinal_final_um']:.3g} µm longitudinal (final)")

    # n_ξ = 104 is the coarsest the arcs allow (≥ 5 elements on each); finer n_ξ need a smaller Δt (CFL)
    grids = [(2, 104, 0.02), (4, 104, 0.02), (6, 104, 0.02), (12, 104, 0.02), (18, 104, 0.02), (18, 156, 0.01),
             (18, 208, 0.01), (36, 208, 0.01)]
    if quick:
        grids = [(4, 104, 0.02), (18, 104, 0.02), (18, 208, 0.01)]
    for ne, nx, dt in grids:
        add(f"grid {ne}×{nx}, Δt {dt:g}", "grid (reuse)", _built(ne, nx, dt, T), DirectBackwardEuler(Reuse()),
            grid=[ne, nx])
    for dt in ((0.01,) if quick else (0.01, 0.005)):
        add(f"Δt {dt:g} (18×104)", "Δt (reuse)", _built(18, 104, dt, T), DirectBackwardEuler(Reuse()), grid=[18, 104])
    default = _built(18, 104, 0.02, T)
    m, n_steps, dt = default
    add("exact (kept interior)", "solver", default, DirectBackwardEuler(KeptInterior()), grid=[18, 104])
    for k in (1, 2):  # refine 0 is the default "grid 18×104" row
        add(f"reuse, refine {k}", "solver", default, DirectBackwardEuler(Reuse(refine=k)), grid=[18, 104])
    rows.update(_integrators(m, dt, rows["grid 18×104, Δt 0.02"], T,
                             (("naive", 1), ("eliminated", 2)) if quick else (("naive", 2), ("eliminated", 5))))
    t, comp, nbytes, u, v = _float32_run(T, repeat)
    rows["float32 (reuse, 18×104)"] = dict(family="precision", n_unknowns=int(m.n_unknowns), dt=0.02, time_s=t,
                                           compile_s=comp, bytes=nbytes, grid=[18, 104], **_errors(u, v, truth))
    _log(f"  float32: {t:.2f} s, {rows['float32 (reuse, 18×104)']['lateral_max_um']:.3g} µm lateral")
    n_train = 50 if quick else 400
    rows.update(_reduced_models(m, n_steps, dt, n_train, (10, 20, 40, None),
                                (10, 20, 40) if quick else (10, 20, 40, 80), repeat, truth))
    payload = {"scene": SCENE, "t_end_s": T, "quick": quick, "repeat": repeat,
               "truth": {"grid": [36, 208], "dt": 0.005, "n_unknowns": int(truth_m.n_unknowns), "run_s": t_truth,
                         "solver": "reuse, refine 2"},
               "rows": rows,
               "wall_s": time.perf_counter() - t_start}
    name = "pareto" + ("_quick" if quick else "")
    path = write_json(out_dir, name, payload)
    (Path(out_dir) / f"{name}.md").write_text(table_markdown(payload))
    plot(payload, Path(out_dir) / f"{name}.png")
    _log(f"wrote {path}")
    return payload


def front_rows(rows, error=lambda r: r["lateral_max_um"]) -> list:
    """The Pareto-optimal candidates in run time and ``error(row)`` (default the lateral error, the
    design quantity), fastest first. Which grid meets a given accuracy is
    :func:`jaxbelt.accuracy.choose_grid`'s to say (``benchmarks/accuracy_trade.py``), not this
    table's: its error is against one truth on one horizon."""
    names = list(rows)
    front = _front([(rows[n]["time_s"], error(rows[n])) for n in names])
    return sorted(({"name": names[i], **rows[names[i]]} for i in front), key=lambda r: r["time_s"])


def table_markdown(payload) -> str:
    """The Pareto front of the lateral error against the run time, as a Markdown table."""
    lines = [f"The Pareto front (lateral error against run time) on `{payload['scene']}` over "
             f"{payload['t_end_s']:g} s (truth 36 × 208, Δt 0.005 s). For the grid that meets an accuracy, ask "
             "`--accuracy-um` (the trade as it chooses: `accuracy_trade`).", "",
             "| candidate | run time (s, 2-core CPU) | memory (MiB) | lateral error (µm) | longitudinal error at T (µm) |",
             "|---|---|---|---|---|"]
    for r in front_rows(payload["rows"]):
        mem = "" if r.get("bytes") is None else f"{r['bytes'] / 2**20:.1f}"
        lines.append(f"| {r['name']} | {r['time_s']:.3g} | {mem} | {r['lateral_max_um']:.3g} | "
                     f"{r['longitudinal_final_um']:.3g} |")
    return "\n".join(lines) + "\n"


def _front(points):
    """Indices of the Pareto-optimal points (lower is better in both coordinates)."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], np.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def plot(payload, path: Path) -> None:
    import matplotlib.pyplot as plt  # backend: the environment's (the CLI sets MPLBACKEND=Agg)

    rows = payload["rows"]
    fams = sorted({r["family"] for r in rows.values()})
    markers = dict(zip(fams, "osD^vP*X"))
    fig, axes = plt.subplots(1, 3, figsize=(16, 5), constrained_layout=True)
    floor = 1e-4
    specs = [("time_s", "lateral_max_um", "wall time of the run (s)", "max lateral tracer error (µm)"),
             ("bytes", "lateral_max_um", "memory of the compiled run (MiB)", "max lateral tracer error (µm)"),
             ("time_s", "longitudinal_final_um", "wall time of the run (s)", "longitudinal tracer error at T (µm)")]
    for ax, (xk, yk, xl, yl) in zip(axes, specs):
        pts, seen = [], set()
        for name, r in rows.items():
            if r.get(xk) is None:
                continue
            x = r[xk] / 2**20 if xk == "bytes" else r[xk]
            y = max(r[yk], floor)
            pts.append((x, y, name))
            ax.loglog(x, y, markers[r["family"]], color=f"C{fams.index(r['family'])}", ms=7,
                      mfc="none" if r.get("projected") else None,
                      label=None if r["family"] in seen else r["family"])
            seen.add(r["family"])
        front = _front([(p[0], p[1]) for p in pts])
        fp = sorted((pts[i] for i in front), key=lambda p: p[0])
        ax.step([p[0] for p in fp], [p[1] for p in fp], "k--", where="post", lw=0.8, alpha=0.6)
        for i in front:
            ax.annotate(pts[i][2], (pts[i][0], pts[i][1]), fontsize=7, xytext=(3, 3), textcoords="offset points")
        ax.axhline(20.0, color="r", lw=0.8, alpha=0.5)
        ax.set_xlabel(xl)
        ax.set_ylabel(yl)
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{payload['scene']}, {payload['t_end_s']:g} s: error against cost (Pareto front dashed; "
                 f"red: the 20 µm design tolerance; hollow: time projected from a few steps)", fontsize=10)
    fig.savefig(path, dpi=110)
    plt.close(fig)
