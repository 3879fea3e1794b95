"""How good the discretisation-error estimate is: effectivity against a run refined 4× in each
direction, on held-out cases, and its cost.

For each case (1D and 2D, open and closed loop, with and without lateral transport, with
misalignments, tension rollers and pre-tension), :func:`jaxbelt.accuracy.estimate_error` on the
case's grid, and the "truth": the same scene refined 4× along the belt, 4× across (2D) and in
Δt (CFL number kept). True error = the largest ``|Q − Q_truth|`` over the tracers and the case's
output times; effectivity = estimate / true error, per quantity (longitudinal ``u``, lateral
``v``). The goal: effectivity within 1–3. Cost: the estimate's runs (compilation apart) as a
multiple of the case's run, and the estimate's whole wall time (compilation included).

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/error_estimate.py [--only NAME]``.
Writes ``results/error_estimate.json`` and ``results/error_estimate.png``.
"""

import argparse
import time

import numpy as np
from _common import RESULTS, write

import jaxbelt as jb
from jaxbelt.accuracy import at_times, tracer_run, estimate_error, refine

COARSE_2D = {"extends": "two-roller-1d", "model": {"kind": "2d"},
             "mesh": {"n_eta": 3, "roller_elements": [6, 6], "free_elements": [8, 8]},
             "time": {"dt_s": 0.02}}
COARSE_THREE = {"mesh": {"n_eta": 3, "roller_elements": [5, 5, 5], "free_elements": [10, 7, 7]}}


def _merge(base: dict, extra: dict) -> dict:
    out = dict(base)
    for k, v in extra.items():
        out[k] = {**out[k], **v} if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


CASES = {
    # 1D: the source's two-roller string (drive + idle), its tension-roller and pre-tension variants
    "1d two-roller": {"extends": "two-roller-1d", "time": {"t_end_s": 0.5}},
    "1d tension roller": {"extends": "two-roller-1d-tension", "time": {"t_end_s": 0.5}},
    "1d idle translated": {"extends": "two-roller-1d-idle-translated", "time": {"t_end_s": 0.5}},
    "1d three-roller": {"extends": "three-roller-1d", "time": {"t_end_s": 0.3}},
    # 2D without lateral transport (the source's variant): a roller tilted and translated
    "2d tilt, no lateral transport": _merge(COARSE_2D, {
        "time": {"t_end_s": 2.0}, "variant": {"idle": {"rotation_mrad": [0.5, 0.3, 0.0], "translation_mm": [0, 0, 1.0]}}}),
    "2d three-roller t72, no lateral transport": _merge(COARSE_THREE, {
        "extends": "three-roller-t72", "time": {"t_end_s": 2.0}}),
    # 2D with lateral transport, open loop: a skewed and a twisted roller (the belt walks)
    "2d skew, lateral transport": _merge(COARSE_2D, {
        "belt": {"length_mm": 863.0}, "solver": {"lateral_transport": True}, "time": {"t_end_s": 4.0},
        "variant": {"idle": {"rotation_mrad": [0.0, 0.3, 0.0]}}}),
    "2d twist, lateral transport": _merge(COARSE_2D, {
        "belt": {"length_mm": 863.0}, "solver": {"lateral_transport": True}, "time": {"t_end_s": 4.0},
        "variant": {"idle": {"rotation_mrad": [0.3, 0.0, 0.0]}}}),
    # closed loop: the steered machines
    "2d two-roller steered": {"extends": "two-roller-steered", "time": {"t_end_s": 4.0}},
    "2d three-roller steered": _merge(COARSE_THREE, {
        "extends": "three-roller-steered", "time": {"t_end_s": 2.0},
        "variant": {"roller 1": {"rotation_mrad": [0.2, 0.0, 0.0]}}}),
    "2d tension roller": _merge(COARSE_THREE, {"extends": "three-roller-tension", "time": {"t_end_s": 2.0}}),
}


NO_RESPONSE_UM = 1e-3  # below this on both sides the quantity does not respond (no lateral motion)


def _effectivity(est, true):
    if true is None or est is None or max(est, true) < NO_RESPONSE_UM:
        return None
    return est / true


def truth_error(scene, est_dt):
    """``(true_u_um, true_v_um, truth_run_s)``: the scene's run against the run refined 4× in
    every direction, at the scene's output times."""
    own = tracer_run(scene)
    fine_scene = refine(scene, n_xi=4.0, n_eta=4.0, dt=4.0)
    fine = tracer_run(fine_scene)
    k = len(own.t)
    qu, qv = at_times(own, scene.time.dt, scene.time.dt, k)
    fu, fv = at_times(fine, fine_scene.time.dt, scene.time.dt, k)
    tv = None if qv is None else float(np.max(np.abs(qv - fv)) * 1e6)
    return float(np.max(np.abs(qu - fu)) * 1e6), tv, fine.run_s


def _fmt(e):
    return "  -  " if e is None else f"{e:.2f}"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--only", default=None, help="run only the cases whose name contains this")
    a = ap.parse_args()
    rows = []
    for name, d in CASES.items():
        if a.only and a.only not in name:
            continue
        scene = jb.scene_from_dict(d, name=name)
        t0 = time.perf_counter()
        est = estimate_error(scene)
        true_u, true_v, truth_s = truth_error(scene, est)
        row = dict(case=name, kind=scene.kind, lateral_transport=scene.solver.lateral_transport,
                   closed_loop=bool(scene.control), grid=dict(n_xi=est.grid.n_xi, n_eta=est.grid.n_eta, dt_s=est.grid.dt),
                   estimate=est.to_dict(), true_longitudinal_um=true_u, true_lateral_um=true_v,
                   effectivity_longitudinal=_effectivity(est.longitudinal_um, true_u),
                   effectivity_lateral=_effectivity(est.lateral_um, true_v),
                   cost_runs=est.cost_runs, estimate_wall_s=est.estimate_s, run_s=est.run_s,
                   truth_run_s=truth_s, case_wall_s=time.perf_counter() - t0)
        rows.append(row)
        lat = "" if true_v is None else (f"  v: est {est.lateral_um:8.3f} true {true_v:8.3f} µm "
                                         f"eff {_fmt(row['effectivity_lateral'])}")
        print(f"{name:44s} u: est {est.longitudinal_um:8.3f} true {true_u:8.3f} µm eff "
              f"{_fmt(row['effectivity_longitudinal'])}{lat}  dominant {est.dominant}  cost {est.cost_runs:.1f}× "
              f"({est.estimate_s:.0f} s wall)", flush=True)
    effs = [r[k] for r in rows for k in ("effectivity_longitudinal", "effectivity_lateral") if r[k] is not None]
    summary = dict(n_cases=len(rows), n_effectivities=len(effs),
                   effectivity_min=min(effs) if effs else None, effectivity_max=max(effs) if effs else None,
                   within_1_3=sum(1.0 <= e <= 3.0 for e in effs),
                   cost_runs_median=float(np.median([r["cost_runs"] for r in rows])) if rows else None)
    print(summary)
    if not a.only:
        write("error_estimate", dict(rows=rows, summary=summary))
        _plot(rows)


def _plot(rows):
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 5))
    for key, marker, label in (("longitudinal", "o", "longitudinal u"), ("lateral", "s", "lateral v")):
        pts = [(r[f"true_{key}_um"], r["estimate"][key]) for r in rows if r[f"true_{key}_um"]]
        if pts:
            t, e = np.array(pts).T
            ax.loglog(t, e, marker, label=label)
    lo = min(min(r["true_longitudinal_um"] for r in rows), 1e-3)
    hi = max(max(r["estimate"]["longitudinal"] for r in rows), max((r["estimate"]["lateral"] or 0) for r in rows)) * 2
    x = np.array([lo, hi])
    ax.loglog(x, x, "k-", lw=0.8, label="effectivity 1")
    ax.loglog(x, 3 * x, "k--", lw=0.8, label="effectivity 3")
    ax.set_xlabel("true error (against 4× refined run), µm")
    ax.set_ylabel("estimated error, µm")
    ax.set_title("Discretisation-error estimate on held-out cases")
    ax.legend()
    fig.tight_layout()
    fig.savefig(RESULTS / "error_estimate.png", dpi=120)


if __name__ == "__main__":
    main()
