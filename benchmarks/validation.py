"""The validation set of ``tests/integration/test_validation.py`` at finer resolution.

The checks, their theory and the test's numbers are in that module's docstring; this script
imports its measurement functions and runs them where the tests cannot afford to:

1. wave speed: 1D on h = 10 … 1.25 mm × c Δt = 4 … 0.5 mm (the numerical dispersion), the
   moving belt (V = 100 m/s) at the finest, and 2D at ν = 0.34 over belt widths 5 … 400 mm
   (n_η = 9): bar speed for a narrow belt, plate speed ``c/√(1 − ν²)`` for a wide one;
2. support loads, drive torque, start-up impulse (exact; recorded as relative errors);
3. lateral translation of a roller on three meshes: the static span against the clamped-guided
   Timoshenko beam (and the tensioned beam), the running default variant against the
   carried-rotation shape, and the relaxation with lateral transport over 12 loops;
4. convergence on ``three-roller-t72`` at t = 0.72 s against fine truths: Δt 0.02 → 0.00125 s
   (truth 0.0003125), n_η 3 → 17 (truth 33), n_ξ 104 → 832 with Δt ∝ ℓ (truth 3328);
5. Backward Euler's damping for θ = ωΔt from 0.013 to 7.9.

Writes ``results/validation.json`` and ``results/validation.png``. Runs in about 10 minutes.
"""

import sys
import time
from pathlib import Path

import numpy as np

from _common import RESULTS, write

TESTS = Path(__file__).resolve().parents[1] / "tests"
sys.path[:0] = [str(TESTS / "integration"), str(TESTS)]  # the test module and its helpers
import test_validation as tv  # noqa: E402  (the checks and their theory live with the tests)


def wave():
    rows = []
    for h in (10.0, 5.0, 2.5, 1.25):
        for c_dt in (4.0, 2.0, 1.0, 0.5):
            model, mesh, opts = tv.compiled(tv.wave_scene("1d", h_mm=h, c_dt_mm=c_dt))
            down, up, _ = tv.wave_speeds(model, mesh, opts, tv.REST)
            rows.append({"h_mm": h, "c_dt_mm": c_dt, "c_m_s": (down + up) / 2, "error": (down + up) / (2 * tv.C0) - 1})
            print(f"wave 1D h {h:5.2f} mm  c dt {c_dt:4.2f} mm  c/c0 - 1 = {rows[-1]['error']:+.4%}", flush=True)
    V = 100.0
    model, mesh, opts = tv.compiled(tv.wave_scene("1d", h_mm=1.25, c_dt_mm=0.5, speed=V))
    down, up, _ = tv.wave_speeds(model, mesh, opts, V)
    moving = {"V_m_s": V, "downstream_m_s": down, "upstream_m_s": up, "down_error": down / (tv.C0 + V) - 1,
              "up_error": up / (tv.C0 - V) - 1, "V_measured_m_s": (down - up) / 2}
    print(f"wave 1D V = 100 m/s: c+V {moving['down_error']:+.4%}, c-V {moving['up_error']:+.4%}, "
          f"V measured {moving['V_measured_m_s']:.2f} m/s", flush=True)
    widths = []
    for w, nu in [(50.0, 0.0)] + [(w, tv.NU) for w in (5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 400.0)]:
        model, mesh, opts = tv.compiled(tv.wave_scene("2d", width_mm=w, nu=nu, n_eta=9))
        down, up, _ = tv.wave_speeds(model, mesh, opts, tv.REST)
        widths.append({"width_mm": w, "nu": nu, "c_over_c0": (down + up) / (2 * tv.C0)})
        print(f"wave 2D w {w:5.0f} mm  nu {nu:.2f}  c/c0 = {widths[-1]['c_over_c0']:.4f}", flush=True)
    return {"c0_m_s": tv.C0, "plate_over_c0": 1 / np.sqrt(1 - tv.NU**2), "sigma_mm": tv.SIGMA_MM, "dispersion": rows,
            "moving": moving, "widths_2d": widths}


def statics():
    out = {}
    for name, r in {**tv.run_statics_1d(), **tv.run_statics_2d()}.items():
        out[name] = {"tension_n": float(r["tension_hand"]),
                     "support_max_error_over_T": float(np.abs(r["support"] - r["support_hand"]).max()
                                                       / r["tension_hand"]),
                     "steady_drive_torque_nm": float(r["steady_torque"]),
                     "impulse_relative_error": float(r["impulse"] / r["impulse_hand"] - 1)}
        print(name, out[name], flush=True)
    return out


def lateral():
    rows = []
    for span, arc, n_eta, dt in ((40, 10, 5, 0.02), (80, 20, 9, 0.01), (160, 40, 9, 0.005)):
        mesh = dict(span=span, arc=arc, n_eta=n_eta, dt=dt)
        steps = int(round(8.0 / dt))  # 3.2 loops at 1 m/s
        free, tens = tv.run_lateral(0.0, steps, **mesh), tv.run_lateral(1e-3, steps, **mesh)
        carried = tv.carried_rotation_shape(tv.XI)
        _, s1, s2 = free["running"]
        rows.append({
            **mesh,
            "static_error_over_d": float(max(np.abs(free["static"][1] - free["shape_hand"]).max(),
                                             np.abs(free["static"][2] - free["shape_hand"][::-1]).max())),
            "static_support_over_hand": float(free["support"][0] / free["support_hand"]),
            "tensioned_error_over_d": float(np.abs(tens["static"][1] - tens["shape_hand"]).max()),
            "tensioned_support_over_hand": float(tens["support"][0] / tens["support_hand"]),
            "running_error_over_d": float(max(np.abs(s1 - carried).max(), np.abs(s2 - (1 - carried)).max())),
            "running_support_over_static": float(free["support"][-1] / free["support"][0]),
            "running_span1_over_d": s1.tolist(), "static_span1_over_d": free["static"][1].tolist()})
        print("lateral", {k: v for k, v in rows[-1].items() if not k.endswith("_over_d") or "error" in k}, flush=True)
    lt = tv.run_lateral(0.0, 1500, lateral_transport=True)
    loop = 2 * tv.LAT["L"] + 2 * np.pi * tv.LAT["r"]
    every = slice(4, None, 5)  # every 5th step (0.1 s) is enough for the plot
    relax = {"loops": (np.arange(1, 1501) * 0.02 / loop)[every].tolist(),
             "ptp_over_d": np.ptp(lt["history"], axis=1)[every].tolist(),
             "support_over_static": (lt["support"] / lt["support"][0])[every].tolist(),
             "final_over_d": lt["history"][-1].tolist()}
    print(f"lateral transport: after 12 loops ptp(v)/d = {relax['ptp_over_d'][-1]:.2e}, "
          f"support/static = {relax['support_over_static'][-1]:.2e}", flush=True)
    return {"xi": tv.XI.tolist(), "timoshenko": tv.beam_shapes(tv.XI)[0].tolist(),
            "carried_rotation": tv.carried_rotation_shape(tv.XI).tolist(), "meshes": rows, "lateral_transport": relax}


def convergence():
    studies = {
        "dt": ([(3, 0.02 / 2**k, 104) for k in range(5)], (3, 0.02 / 2**6, 104)),
        "n_eta": ([(n, 0.02, 104) for n in (3, 5, 9, 17)], (33, 0.02, 104)),
        "n_xi": ([(3, 0.02 / 2**k, 104 * 2**k) for k in range(4)], (3, 0.02 / 2**5, 104 * 2**5)),
    }
    out = {}
    for name, (levels, truth) in studies.items():
        t0 = time.perf_counter()
        ref = tv.t72_tracers(*truth)
        runs = [tv.t72_tracers(*lv) for lv in levels]
        res = {"levels": [list(lv) for lv in levels], "truth": list(truth)}
        for k, comp in ((0, "u"), (1, "v")):
            err = np.array([np.linalg.norm(r[k] - ref[k]) for r in runs])
            res[f"error_{comp}_m"] = err.tolist()
            res[f"order_{comp}_truth"] = np.log2(err[:-1] / err[1:]).tolist()
            res[f"order_{comp}_richardson"] = [tv.observed_orders(runs[i:i + 3])[k] for i in range(len(runs) - 2)]
        out[name] = res
        print(f"convergence {name} ({time.perf_counter() - t0:.0f} s):",
              {k: np.round(v, 3).tolist() for k, v in res.items() if k.startswith("order")}, flush=True)
    out["expected"] = {"dt": 1.0, "n_eta": f"2 lambda = {2 * tv.corner_exponent():.3f} (corner) to 2 (smooth)",
                       "n_xi": ">= 1 (first-order transport and BE at a fixed Courant number)"}
    return out


def damping():
    rows = []
    for c_dt, steps in ((2.0, 40), (20.0, 5)):
        model, mesh, opts = tv.compiled(tv.wave_scene("1d", c_dt_mm=c_dt))
        theta, residual, amp_err, ratio = tv.be_damping(model, mesh, opts, steps=steps)
        for k, th in enumerate(theta):
            theory = 1 / (1 + th**2)
            rows.append({"theta": float(th), "energy_ratio_theory": theory, "energy_ratio_mean": float(ratio[k].mean()),
                         "energy_ratio_max_rel_dev": float(np.abs(ratio[k] / theory - 1).max()),
                         "amplitude_max_error": float(amp_err[k]), "eigen_residual": float(residual[k])})
            print("damping", rows[-1], flush=True)
    return rows


def plot(res, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker  # noqa: F401

    fig, ax = plt.subplots(2, 3, figsize=(16, 9), constrained_layout=True)
    a = ax[0, 0]
    disp = res["wave"]["dispersion"]
    for c_dt in sorted({r["c_dt_mm"] for r in disp}, reverse=True):
        rs = [r for r in disp if r["c_dt_mm"] == c_dt]
        a.loglog([r["h_mm"] for r in rs], [abs(r["error"]) for r in rs], "o-", label=f"c Δt = {c_dt:g} mm")
    a.axhline(0.02, color="k", ls=":", label="tolerance 2 %")
    a.set_xticks([1.25, 2.5, 5, 10], ["1.25", "2.5", "5", "10"])
    a.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    a.set(xlabel="element length h, mm", ylabel="|c_measured / √(E/ρ) − 1|",
          title="1D wave speed: numerical dispersion")
    a.legend(fontsize=8)
    a = ax[0, 1]
    ws = [r for r in res["wave"]["widths_2d"] if r["nu"] > 0]
    a.semilogx([r["width_mm"] / res["wave"]["sigma_mm"] for r in ws], [r["c_over_c0"] for r in ws], "o-",
               label="2D, ν = 0.34")
    a.axhline(1.0, color="k", lw=0.8, label="bar √(E/ρ)")
    a.axhline(res["wave"]["plate_over_c0"], color="tab:red", lw=0.8, label="plate √(E/(ρ(1−ν²)))")
    a.set(xlabel="belt width / pulse σ", ylabel="c / √(E/ρ)", title="2D wave speed: bar → plate")
    a.legend(fontsize=8)
    a = ax[0, 2]
    th = np.logspace(-2.2, 1.0, 200)
    a.semilogx(th, 1 / (1 + th**2), "k-", label="1 / (1 + θ²)")
    a.semilogx([r["theta"] for r in res["damping"]], [r["energy_ratio_mean"] for r in res["damping"]], "o",
               label="model")
    a.set(xlabel="θ = ω Δt", ylabel="energy ratio per step", title="Backward Euler damping of a free mode")
    a.legend(fontsize=8)
    a = ax[1, 0]
    lat = res["lateral"]
    xi = np.array(lat["xi"])
    fine = np.linspace(0, 1, 101)
    a.plot(fine, 3 * fine**2 - 2 * fine**3, "k-", lw=0.8, label="clamped-guided beam")
    a.plot(fine, -3 * fine + 6 * fine**2 - 2 * fine**3, "r-", lw=0.8, label="carried rotation, M(L) = 0")
    for row, mk in zip(lat["meshes"], "os^"):
        a.plot(xi, row["static_span1_over_d"], "k" + mk, mfc="none", label=f"static, {row['span']} el./span")
        a.plot(xi, row["running_span1_over_d"], "r" + mk, mfc="none", label=f"running (default), {row['span']}")
    a.plot(xi, np.array(lat["lateral_transport"]["final_over_d"])[5:10], "bD", label="running, lateral transport")
    a.set(xlabel="ξ along span 1 (roller 1 → translated roller 2)", ylabel="v / d",
          title="lateral roller translation")
    a.legend(fontsize=7)
    a = ax[1, 1]
    conv = res["convergence"]
    for name, color in (("dt", "tab:blue"), ("n_eta", "tab:green"), ("n_xi", "tab:red")):
        h = 2.0 ** -np.arange(len(conv[name]["error_u_m"]))
        for comp, style in (("u", "o-"), ("v", "s--")):
            e = np.array(conv[name][f"error_{comp}_m"])
            a.loglog(h, e / e[0], style, color=color, label=f"{name}: {comp}")
    a.loglog([1, 1 / 8], [1, 1 / 8], "k:", lw=0.8, label="slope 1")
    a.loglog([1, 1 / 8], [1, 1 / 64], "k-.", lw=0.8, label="slope 2")
    a.set(xlabel="refinement (h / h₀, Δt / Δt₀)", ylabel="tracer error / coarsest",
          title="three-roller-t72: observed orders")
    a.legend(fontsize=7, ncol=2)
    a = ax[1, 2]
    rl = lat["lateral_transport"]
    a.semilogy(rl["loops"], rl["ptp_over_d"], label="spread of v over the tracers / d")
    a.semilogy(rl["loops"], np.abs(rl["support_over_static"]), label="|z support load| / static")
    a.set(xlabel="loops", title="lateral transport: the belt straightens")
    a.legend(fontsize=8)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    print(f"wrote {path}")


def main():
    t0 = time.perf_counter()
    res = {"wave": wave(), "damping": damping(), "statics": statics(), "lateral": lateral(),
           "convergence": convergence()}
    res["wall_s"] = time.perf_counter() - t0
    write("validation", res)
    plot(res, RESULTS / "validation.png")


if __name__ == "__main__":
    main()
