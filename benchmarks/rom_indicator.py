"""The a-posteriori error estimate of the reduced models (``jaxbelt.rom.error_estimate.error_rom`` times
the safety factor calibrated on the training data) against the true error, on configurations no
fit has seen — every number from ``jaxbelt reduce --json`` itself (in this process, so compiled
programs are shared between cases).

Effectivity = estimate / true error, for the tracer RMSE over the predicted steps (``rmse_um``,
estimated by ``error_estimate_um``) and for its maximum over time (``max_rmse_over_time_um``,
``error_estimate_max_um``), all in µm. Target: between 1 and 3.

Cases:
1. 1D (``two-roller-1d``, N = 224; training runs of 150 steps, 400 predicted): the drive moved
   -6 mm (held out; DMDc trained on the nominal scene and Table 6.1 run 1, same speed) and the
   drive moved -6 mm at 0.45 m/s (POD and parametric DMD, trained on the nominal scene and Table
   6.1 runs 1-2, which vary the speed); single-configuration DMD on Table 6.1 runs 1 and 2.
2. 2D default scene ``three-roller-t72`` (N = 3762): DMD and POD on its own first 400 steps,
   1500 predicted.
3. 2D multi-configuration, trained on the nominal scene and the source's Table 7.4 runs (200
   steps each), 1000 steps predicted: Table A.1 runs 4 and 9 and Table 7.3 tests 1-2 (roller 3
   moved along x, a direction no training run varied), POD (20 modes) and DMDc (30); and Table
   A.1 run 9 over the whole 100 s (5000 steps).
4. 2D box (``--train-ranges``: every component of the three rollers, +-3 mm / +-0.5 mrad, the
   axial design of 31 runs of 100 steps; ``benchmarks/rom_box_2d.py``'s box), 600 steps predicted:
   ``three-roller-t72`` and a configuration drawn uniformly in the box, POD and DMDc (40 modes).

Ablation (1D held-out cases of 1., library calls, raw estimates without the safety factor): the
triangle-inequality indicator (sum of one-step residuals, :func:`jaxbelt.rom.residual_indicator`), point residual samples every 10th
step, window-mean residuals of 10 steps, the same with the first 10 steps each their own window,
then with the windows whose mean residual still changes cut into single steps, then with the
quasi-static response added to the subspace (the default), and every step's residual (no
sampling error: what is left is the linearisation and the subspace), without and with the
quasi-static response.

Writes ``results/rom_indicator.json`` and ``results/rom_indicator.png``.
Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/rom_indicator.py [--quick | --ablation-only]`` (about
an hour on a shared 2-core machine; ``--quick``: the 1D cases and the t72 DMD; ``--ablation-only``:
recompute only the ablation into the existing ``results/rom_indicator.json``).
"""

import contextlib
import io
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _common import RESULTS, load, write
from jaxbelt.cli import main

QUICK = "--quick" in sys.argv
T74 = ["three-roller"] + [f"three-roller-t74-train{i}" for i in range(1, 7)]
BOX = "".join(f'[roller."roller {k}"]\ntranslation_mm = {{dist = "uniform", half_width = [3.0, 3.0, 3.0]}}\n'
              f'rotation_mrad = {{dist = "uniform", half_width = [0.5, 0.5, 0.0]}}\n' for k in (1, 2, 3))


def scenes(folder: Path) -> dict:
    """The variant scene files of the held-out configurations (their text goes into the JSON)."""
    rng = np.random.default_rng(1)
    t = rng.uniform(-3.0, 3.0, (3, 3))
    a = rng.uniform(-0.5, 0.5, (3, 2))
    random_box = 'extends = "three-roller"\n\n' + "".join(
        f'[variant."roller {k + 1}"]\ntranslation_mm = [{t[k, 0]:.4f}, {t[k, 1]:.4f}, {t[k, 2]:.4f}]\n'
        f'rotation_mrad = [{a[k, 0]:.4f}, {a[k, 1]:.4f}, 0.0]\n\n' for k in range(3))
    text = {
        "two-roller-1d-drive6": 'extends = "two-roller-1d"\n\n[variant."drive"]\ntranslation_mm = [-6.0, 0.0, 0.0]\n',
        "two-roller-1d-drive6-slow": 'extends = "two-roller-1d"\n\n[variant."drive"]\ntranslation_mm = [-6.0, 0.0, 0.0]\n'
                                     'speed_m_s = 0.45\n',
        "three-roller-box-random1": random_box,
        "box": BOX,
    }
    paths = {}
    for name, body in text.items():
        p = folder / f"{name}.toml"
        p.write_text(body)
        paths[name] = str(p)
    return paths, text


def cases(p: dict) -> list:
    """``(group, label, argv)`` for every case."""
    one_d = ["--steps", "400", "--train-steps", "150"]
    tr2 = ["--train", "two-roller-1d", "two-roller-1d-train1"]
    tr3 = tr2 + ["two-roller-1d-train2"]
    out = []
    for r in (10, 20, 30):
        out.append(("1D held-out", f"POD r={r}, drive -6 mm at 0.45 m/s",
                    [p["two-roller-1d-drive6-slow"], "--method", "pod", *tr3, "--modes", str(r), *one_d]))
    out.append(("1D held-out", "pDMD r=30, drive -6 mm at 0.45 m/s",
                [p["two-roller-1d-drive6-slow"], "--method", "pdmd", *tr3, *one_d]))
    for r in (10, 30):
        out.append(("1D held-out", f"DMDc r={r}, drive -6 mm",
                    [p["two-roller-1d-drive6"], "--method", "dmdc", *tr2, "--modes", str(r), *one_d]))
    for s in ("two-roller-1d-train1", "two-roller-1d-train2"):
        out.append(("1D single", f"DMD, {s}", [s, "--method", "dmd", *one_d]))
    out.append(("2D t72", "DMD, three-roller-t72", ["three-roller-t72", "--method", "dmd", "--steps", "1500",
                                                      "--train-steps", "400"]))
    if QUICK:
        return out
    for r in (5, 10):
        out.append(("2D t72", f"POD r={r}, three-roller-t72", ["three-roller-t72", "--method", "pod", "--modes", str(r),
                                                               "--steps", "1500", "--train-steps", "400"]))
    multi = ["--train", *T74, "--steps", "1000", "--train-steps", "200"]
    for scene in ("three-roller-a1-run9", "three-roller-a1-run4", "three-roller-t73-test1", "three-roller-t73-test2"):
        for meth in ("pod", "dmdc"):
            out.append(("2D Table 7.4-trained", f"{meth.upper() if meth == 'pod' else 'DMDc'} "
                        f"r={20 if meth == 'pod' else 30}, {scene.replace('three-roller-', '')}",
                        [scene, "--method", meth, *multi]))
    out.append(("2D Table 7.4-trained", "POD r=20, a1-run9, 5000 steps (100 s)",
                ["three-roller-a1-run9", "--method", "pod", "--train", *T74, "--train-steps", "200"]))
    box = ["--train-ranges", p["box"], "--modes", "40", "--steps", "600", "--train-steps", "100"]
    for scene, label in (("three-roller-t72", "t72"), (p["three-roller-box-random1"], "random in the box")):
        for meth in ("pod", "dmdc"):
            out.append(("2D box", f"{'POD' if meth == 'pod' else 'DMDc'} r=40, {label}", [scene, "--method", meth, *box]))
    return out


def run_case(argv):
    buf = io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(buf):
        rc = main(["reduce", *argv, "--json"])
    wall = time.perf_counter() - t0
    if rc != 0:
        return dict(exit_code=rc)
    r = json.loads(buf.getvalue())
    e = r["error_estimate"]
    return dict(
        scene=r["scene"], method=r["method"], modes=r["modes"], predict_steps=r["predict_steps"], compared=r["compared"],
        rmse_um=r["rmse_um"], error_estimate_um=r["error_estimate_um"], effectivity=r["effectivity"],
        max_rmse_over_time_um=r["max_rmse_over_time_um"], error_estimate_max_um=r["error_estimate_max_um"],
        effectivity_max=r["error_estimate_max_um"] / r["max_rmse_over_time_um"],
        raw_effectivity=e["raw_rmse_um"] / r["rmse_um"], safety_factor=e["safety_factor"],
        calibration_effectivities=[c["effectivity"] for c in e["calibration"]], cost=e["cost"],
        subspace_dim=e["subspace_dim"], estimate_s=r["timings"]["error_estimate_total_s"],
        estimate_test_s=r["timings"]["error_estimate_s"],
        full_run_s=r["timings"]["full_run_s"], full_mode=r["timings"]["full_mode"], wall_s=wall)


def ablation(paths):
    """Raw effectivities of the estimator's variants on the 1D held-out cases."""
    import jax.numpy as jnp

    import jaxbelt as jb
    from jaxbelt.rom import (ErrorRomOptions, belt_inputs, collect_first_order, error_rom, fit_dmdc,
                             fit_reduced_pod_ranks, parameters, residual_indicator, rmse, stack_controlled,
                             tracer_operator)

    names = ["two-roller-1d", "two-roller-1d-train1", "two-roller-1d-train2"]
    ms = [load(n)[0] for n in names]
    dt = load(names[0])[1].dt  # the 1D scenes share their time step
    runs = [collect_first_order(m, jb.RunOptions(jb.make_solver(), 150, dt)) for m in ms]
    slow, same = load(paths["two-roller-1d-drive6-slow"])[0], load(paths["two-roller-1d-drive6"])[0]
    C = tracer_operator(ms[0])
    Cz = jnp.concatenate([C, jnp.zeros_like(C)], axis=1)
    n = 400
    tests = []
    roms = fit_reduced_pod_ranks(ms[0], jnp.concatenate([z for r in runs for z in r[1:]], axis=1), (10, 20, 30), dt)
    Zs = collect_first_order(slow, jb.RunOptions(jb.make_solver(), n, dt))[2]
    for r, rom in roms.items():
        xi0 = rom.project(slow, jb.initial_state(slow))
        o = rom.run(xi0, parameters(slow), n)
        tests.append((f"POD r={r}", slow, rom.basis, jnp.concatenate([xi0[None], o.xi]), Zs, o.tracer_u))
    post = [r[2] for r in runs[:2]]
    X, Y, U = stack_controlled(post, [belt_inputs(parameters(m), z.shape[1] - 1) for m, z in zip(ms[:2], post)])
    Zd = collect_first_order(same, jb.RunOptions(jb.make_solver(), n, dt))[2]
    u = belt_inputs(parameters(same), 1)[:, 0]
    for r in (10, 30):
        f = fit_dmdc(X, Y, U, rank=r)
        co = jnp.concatenate([(f.basis.T @ Zd[:, 0])[None], f.predict(Zd[:, 0], u, n, observe=f.basis.T)])
        tests.append((f"DMDc r={r}", same, f.basis, co, Zd, f.predict(Zd[:, 0], u, n, observe=Cz)))
    plain = dict(refine_rtol=None, quasi_static=False)
    variants = {"point samples, stride 10": (10, dict(dense=0, sampling="point", **plain)),
                "window means, stride 10": (10, dict(dense=0, **plain)),
                "window means, stride 10, first 10 steps single": (10, dict(plain)),
                "window means, stride 25, first 10 steps single": (25, dict(plain)),
                "the same + changing windows single": (10, dict(quasi_static=False)),
                "the same + quasi-static response (default)": (10, dict()),
                "every step (stride 1)": (1, dict(dense=0, **plain)),
                "every step + quasi-static response": (1, dict(dense=0))}
    out = {}
    for label, m, basis, coords, Z, pred in tests:
        true = float(rmse((Cz @ Z[:, 1:]).T, pred)) * 1e6
        row = dict(true_rmse_um=true)
        # the triangle-inequality indicator: the accumulated one-step residual at the last step
        tri = residual_indicator(m, coords @ basis.T, dt, stride=10).estimate_um[-1]
        row["triangle inequality, stride 10"] = float(tri) / true
        for name, (stride, kw) in variants.items():
            est = error_rom(m, basis, coords, dt, z_true0=Z[:, 0], stride=stride, options=ErrorRomOptions(**kw))
            row[name] = est.rmse_um / true
        out[label] = row
        print(label, {k: round(v, 3) for k, v in row.items()}, flush=True)
    return out


def plot(rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(12, 5.2), constrained_layout=True)
    groups = sorted({r["group"] for r in rows})
    markers = dict(zip(groups, "os^Dv<>"))
    colors = {"pod": "tab:blue", "dmd": "tab:orange", "dmdc": "tab:green", "pdmd": "tab:red"}
    for ax, (tk, ek, title) in zip(axes, (("rmse_um", "error_estimate_um", "tracer RMSE over the predicted steps"),
                                          ("max_rmse_over_time_um", "error_estimate_max_um", "max over time of the RMSE"))):
        t = np.array([r[tk] for r in rows])
        e = np.array([r[ek] for r in rows])
        lo, hi = t.min() / 3, t.max() * 10
        x = np.array([lo, hi])
        ax.loglog(x, x, "k-", lw=1, label="effectivity 1")
        ax.loglog(x, 3 * x, "k--", lw=1, label="effectivity 3")
        for r, ti, ei in zip(rows, t, e):
            ax.loglog(ti, ei, markers[r["group"]], color=colors[r["method"]], ms=7, mfc="none" if "1D" in r["group"] else None)
        for g in groups:
            ax.plot([], [], markers[g], color="gray", label=g)
        for mth, c in colors.items():
            ax.plot([], [], "s", color=c, label=mth)
        ax.set(xlabel="true error (µm)", ylabel="estimate (µm)", title=title, xlim=(lo, hi), ylim=(lo, hi))
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=8, loc="upper left")
    fig.suptitle("jaxbelt reduce: error estimate vs true error on held-out configurations")
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main_():
    if "--ablation-only" in sys.argv:  # recompute the ablation into the existing JSON
        with tempfile.TemporaryDirectory() as tmp:
            abl = ablation(scenes(Path(tmp))[0])
        existing = json.loads((RESULTS / "rom_indicator.json").read_text())
        write("rom_indicator", dict(existing, ablation_raw_effectivity=abl))
        return
    with tempfile.TemporaryDirectory() as tmp:
        paths, text = scenes(Path(tmp))
        abl = ablation(paths)
        rows = []
        for group, label, argv in cases(paths):
            res = run_case(argv)
            shown = [a if not a.startswith(tmp) else Path(a).name for a in argv]
            row = dict(group=group, label=label, command="jaxbelt reduce " + " ".join(shown) + " --json", **res)
            rows.append(row)
            if "effectivity" in res:
                print(f"{label:45s} true {res['rmse_um']:.4g} µm est {res['error_estimate_um']:.4g} µm eff {res['effectivity']:.2f} "
                      f"(max {res['effectivity_max']:.2f}; raw {res['raw_effectivity']:.2f}, x{res['safety_factor']:.2f}) "
                      f"cost {res['cost']['full_step_equivalents']} / {res['predict_steps']} steps, {res['wall_s']:.0f} s",
                      flush=True)
            else:
                print(label, res, flush=True)
    ok = [r for r in rows if "effectivity" in r]
    eff = np.array([r["effectivity"] for r in ok] + [r["effectivity_max"] for r in ok])
    summary = dict(n_cases=len(ok), effectivity_min=float(eff.min()), effectivity_max=float(eff.max()),
                   all_within_1_3=bool(np.all((eff >= 1) & (eff <= 3))))
    print(summary)
    name = "rom_indicator_quick" if QUICK else "rom_indicator"
    write(name, dict(summary=summary, cases=rows, ablation_raw_effectivity=abl, scene_files=text))
    plot(ok, RESULTS / f"{name}.png")


if __name__ == "__main__":
    main_()
