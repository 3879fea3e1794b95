"""The modal reduced integrator (the source's §5.1.1/§6.2) beside POD-Galerkin: tracer error
against the number of modes, on the 1D scene and a coarse 2D one.

Modal: the first r modes of the eliminated ODE at the initial state, by frequency and by the
RHS-aware order |φᵀF|/ω (:func:`jaxbelt.rom.fit_modal`); POD: :func:`jaxbelt.rom.fit_pod` trained on
the first ``TRAIN`` steps of the same run. All are the same Galerkin-projected Backward-Euler step
(:class:`jaxbelt.rom.PODGalerkin`), so the comparison is of the bases alone. Error: tracer RMSE
(longitudinal; lateral too in 2D) over the whole run against the eliminated full model, mm.
Run: ``python benchmarks/modal_vs_pod.py``; writes ``results/modal_vs_pod.json`` and ``.png``.
"""

import dataclasses

import numpy as np

import jaxbelt as jb
from _common import RESULTS, load, write
from jaxbelt.rom import collect_snapshots, fit_modal, fit_pod, rmse

TRAIN = 200


def err_mm(ref, tr):
    e = [float(rmse(ref.tracer_u, tr.tracer_u))]
    if ref.tracer_v is not None:
        e.append(float(rmse(ref.tracer_v, tr.tracer_v)))
    return 1e3 * max(e)


def study(model, dt, n_steps, ranks):
    eliminated = jb.make_solver("eliminated")
    _, ref = jb.simulate(model, eliminated, n_steps=n_steps, dt=dt)
    _, X, _ = collect_snapshots(model, jb.RunOptions(eliminated, TRAIN, dt))
    dyn, _ = model.partition
    out = {"n_unknowns": int(model.n_unknowns), "n_dynamic": len(dyn), "steps": n_steps, "ranks": list(ranks),
           "train_steps_pod": TRAIN}
    for name, make in (("modal, forcing order", lambda r: fit_modal(model, r, dt, "forcing")),
                       ("modal, frequency order", lambda r: fit_modal(model, r, dt, "frequency")),
                       ("POD", lambda r: fit_pod(model, X, n_modes=r))):
        out[name] = [err_mm(ref, jb.simulate(model, make(r), n_steps=n_steps, dt=dt)[1]) for r in ranks]
        print(model.kind, name, ["%.3g" % e for e in out[name]], flush=True)
    return out


def main():
    m1, opts1 = load("two-roller-1d-train1")
    res = {"1d": study(m1, opts1.dt, 400, (5, 10, 20, 40, 80))}
    sc = jb.load_scene("three-roller-t72")
    m2, opts2 = load(sc.replace(mesh=dataclasses.replace(sc.mesh, n_eta=4)))
    res["2d (three-roller-t72, n_eta = 4)"] = study(m2, opts2.dt, 400, (10, 20, 40, 80, 160))
    write("modal_vs_pod", res)

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    for ax, (title, r) in zip(axes, res.items()):
        for name in ("modal, forcing order", "modal, frequency order", "POD"):
            ax.semilogy(r["ranks"], np.maximum(r[name], 1e-12), "o-", label=name)
        ax.axhline(0.02, color="r", lw=0.8, label="0.02 mm (source's tolerance)")
        ax.set_xlabel("modes r")
        ax.set_ylabel("tracer RMSE (mm)")
        ax.set_title(f"{title}: N = {r['n_unknowns']}, {r['steps']} steps")
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8)
    fig.savefig(RESULTS / "modal_vs_pod.png", dpi=110)


if __name__ == "__main__":
    main()
