"""The product question on the built-in design scene, end to end, with wall times.

``three-roller-tolerance`` (the aligned ``three-roller`` machine, N = 3762, 4 s = 200 steps):

1. settling: the largest lateral tracer deviation over 10 s for 0.1 mm / 0.1 mrad of three
   components (why the design scene stops at 4 s);
2. sensitivity of ``lateral_max`` to all 15 components (value, gradient, forward and gradient
   wall time);
3. the largest tolerance box for ``lateral_max ≤ 20 µm``, verified by full runs;
4. the yield with every component normal, σ = half-width / 2: Monte Carlo, FORM, importance
   sampling.

Writes ``results/design_default.json`` and ``.png``. ``--quick`` uses n_eta = 6 and fewer samples.
"""

import argparse
import time

import jax.numpy as jnp
import numpy as np

import jaxbelt as jb
from _common import RESULTS, load, write
from jaxbelt import design
from jaxbelt.misalignment import apply, parameter_space


def settling(model, opts, steps=500):
    sp = parameter_space(model, "roller 1:ay,roller 2:ax,roller 3:dz")
    run = opts.replace(n_steps=steps)
    _, ref = jb.simulate(model, **run)
    out = {}
    for k, lab in enumerate(sp.labels()):
        _, tr = jb.simulate(apply(model, sp, jnp.zeros(3).at[k].set(0.1)), **run)
        dv = np.abs(np.asarray(tr.tracer_v) - np.asarray(ref.tracer_v)).max(axis=1) * 1e6
        out[lab] = dv.tolist()
    return np.asarray(ref.t).tolist(), out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--samples", type=int, default=None)
    a = ap.parse_args()
    scene = jb.load_scene("three-roller-tolerance")
    if a.quick:
        scene = scene.replace(mesh=scene.mesh.__class__(n_eta=6, n_xi=104))
    model, opts = load(scene)
    n = a.samples or (100 if a.quick else 400)
    res = {"scene": "three-roller-tolerance", "quick": a.quick, "n_unknowns": model.n_unknowns,
           "steps": opts.n_steps}
    t0 = time.perf_counter()
    t, hist = settling(model, opts)
    res["settling"] = {"t": t, "max_lateral_um": hist, "wall_s": time.perf_counter() - t0}
    for lab, v in hist.items():
        v = np.asarray(v)
        print(f"settling {lab}: {v[199]:.3f} µm at 4 s, {v[-1]:.3f} µm at 10 s")

    t0 = time.perf_counter()
    study = design.make_study(model, "lateral_max", opts)
    res["study_s"] = time.perf_counter() - t0
    rep = design.sensitivity_report(study)
    res["sensitivity"] = rep.to_dict()
    print(f"sensitivity: forward {rep.forward_s:.3f} s, gradient {rep.gradient_s:.3f} s "
          f"(×{rep.gradient_s / rep.forward_s:.2f}), compile {rep.compile_s:.1f} s")

    t0 = time.perf_counter()
    box = design.tolerance_box(study, 20.0)
    box_s = time.perf_counter() - t0
    res["tolerance"] = {**box.to_dict(), "labels": list(box.labels), "wall_s": box_s}
    print(f"tolerance box in {box_s:.1f} s: verified worst {box.worst_case_um:.3f} µm, "
          f"binding {box.binding[:3]}, iterations {box.iterations}")
    for lab, h, u in zip(box.labels, box.half_widths, box.units):
        print(f"  {lab:14s} ± {h:.4g} {u}")

    dist = design.Distribution(tuple(box.labels), ("normal",) * len(box.labels),
                               tuple(np.asarray(box.half_widths) / 2.0))
    t0 = time.perf_counter()
    sw = design.run_sweep(study, dist, n, 20.0, chunk=50, progress=True)
    res["yield"] = {**sw.to_dict(), "wall_s": time.perf_counter() - t0}
    is_yield = float("nan") if sw.is_yield is None else sw.is_yield
    print(f"yield (σ = h/2, {n} samples): MC {sw.yield_:.4f} {sw.ci95}, FORM {sw.form_yield:.6f}, "
          f"IS {is_yield:.6f}; {res['yield']['wall_s']:.1f} s")
    write("design_default" + ("_quick" if a.quick else ""), res)
    plot(res, box, sw.metric_values, RESULTS / ("design_default" + ("_quick" if a.quick else "") + ".png"))


def plot(res, box, metric_values, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a1, a2, a3) = plt.subplots(1, 3, figsize=(15, 4.2), constrained_layout=True)
    t = res["settling"]["t"]
    for lab, v in res["settling"]["max_lateral_um"].items():
        a1.plot(t, v, label=f"{lab} = 0.1")
    a1.axvline(4.0, color="k", ls="--", lw=0.8)
    a1.set_xlabel("t [s]")
    a1.set_ylabel("max |lateral deviation| [µm]")
    a1.set_title("settling of the lateral response")
    a1.legend()
    h = np.asarray(box.half_widths)
    a2.bar(np.arange(len(h)), h, color=["tab:red" if lab in box.binding[:3] else "tab:blue" for lab in box.labels])
    a2.set_yscale("log")
    a2.set_xticks(np.arange(len(h)), box.labels, rotation=70, fontsize=7)
    a2.set_title(f"tolerance box (verified {box.worst_case_um:.2f} µm)")
    a3.hist(metric_values, bins=30)
    a3.axvline(20.0, color="tab:red")
    y = res["yield"]
    a3.set_title(f"yield {y['yield']:.3f} (FORM {y['form_yield']:.4f})")
    a3.set_xlabel("lateral_max [µm]")
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
