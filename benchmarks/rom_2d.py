"""Model order reduction on the 2D default scene (three rollers, N = 3762), side by side with the
source's headline numbers (§7.3, §7.4):

A. POD, one configuration (Table 7.2 run): train on the first ``N_SINGLE`` steps, predict the
   whole 100 s with the fully reduced step; modes needed for 0.02 mm. (The source's POD-Galerkin
   reduced only the solve; ours projects the transport too, so its online cost is O(r²).)
B. DMD from 400 pre-transport snapshots of the same run, predicting the remaining 100 s
   (source: RMSE ~1e-8 m scale, total speedup ≈ 4.8).
C. Multi-configuration: trained on the nominal scene + Table 7.4's six runs (``N_MULTI`` steps
   each), tested on the held-out Table 7.3 tests and Table A.1 runs (18 configurations, 100 s
   each): fully reduced POD, DMD with control, parametric DMD. Total speedup as eq. 7.5:
   (time of the replaced full runs) / (offline training + all reduced runs); source ≈ 2.0 for
   POD multi-config (its multi-config DMD failed).

Full-order runs use the factorisation-reuse solver (the fastest exact-to-1e-13 mode). Writes
``results/rom_2d.json`` and ``results/rom_2d.png``. Takes ~15 min on 2 cores.
"""

import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

import jaxbelt as jb
from _common import clock, load, write
from jaxbelt.rom import (belt_inputs, collect_first_order, fit_dmd, fit_dmdc, fit_parametric_dmd, fit_reduced_pod,
                         fit_reduced_pod_ranks, parameters, rmse, stack_controlled, state_to_z, tracer_operator)

N_SINGLE = 1000  # 20 s of the 100 s run
N_DMD = 400
N_MULTI = 400
TOL = 0.02  # mm
QUICK = "--quick" in sys.argv
REUSE = jb.DirectBackwardEuler(jb.Reuse())


def full_run(m, n, dt):
    return jb.simulate(m, REUSE, n_steps=n, dt=dt)


def err_mm(a, b):
    return float(rmse(a, b)) * 1e3


def main():
    m, opts = load("three-roller-t72")
    dt = opts.dt
    n_full = 500 if QUICK else opts.n_steps
    full_run(m, n_full, dt)  # compile
    t_full, (_, ref) = clock(full_run, m, n_full, dt)
    print(f"full run {n_full} steps: {t_full:.2f} s")
    out = {"scene": "three-roller-t72", "n_steps": n_full, "full_run_s": t_full, "tol_mm": TOL}

    # ---------- A: POD single configuration ----------
    n_single = min(N_SINGLE, n_full // 2)
    t_snap, (_, Zp, Zq) = clock(lambda: collect_first_order(m, jb.RunOptions(REUSE, n_single, dt)))
    Z = jnp.concatenate([Zp, Zq], axis=1)
    st0 = jb.initial_state(m)
    pod = {}
    # every rank from one projection at the largest (ReducedStep.truncate): compiled once, not per rank
    t_fit, roms = clock(lambda: fit_reduced_pod_ranks(m, Z, (5, 10, 20, 40), dt, jb.make_solver("direct")))
    for r, rom in roms.items():
        xi0 = rom.project(m, st0)
        run = jax.jit(lambda x: rom.run(x, parameters(m), n_full))
        run(xi0)
        t_on, pr = clock(run, xi0)
        pod[r] = dict(rmse_x_mm=err_mm(ref.tracer_u, pr.tracer_u), rmse_z_mm=err_mm(ref.tracer_v, pr.tracer_v),
                      offline_s=t_snap + t_fit, online_s=t_on, speedup_online=t_full / t_on,
                      speedup_total=t_full / (t_snap + t_fit + t_on))
        print(f"POD r={r}: {pod[r]}")
    ok = [r for r in pod if max(pod[r]["rmse_x_mm"], pod[r]["rmse_z_mm"]) < TOL]
    out["pod_single"] = dict(train_steps=n_single, by_modes=pod, modes_for_tol=min(ok) if ok else None,
                             singular_values=np.asarray(rom.singular_values[:200]).tolist())

    # ---------- B: DMD from 400 snapshots (pre-transport, source's setup) ----------
    n_dmd = min(N_DMD, n_full // 2)
    t_snap, (_, Zp, _) = clock(lambda: collect_first_order(m, jb.RunOptions(REUSE, n_dmd, dt)))
    t_fit, dmd = clock(lambda: fit_dmd(Zp))
    C = tracer_operator(m)
    obs = jnp.concatenate([jnp.concatenate([C, jnp.zeros_like(C)], 1),
                           jnp.concatenate([tracer_operator(m, "z"), jnp.zeros_like(C)], 1)])
    n_pred = n_full - n_dmd
    pred_fn = jax.jit(lambda x: dmd.predict(x, n_pred, observe=obs))
    pred_fn(Zp[:, -1])
    t_on, pred = clock(pred_fn, Zp[:, -1])
    ntr = C.shape[0]
    truth_x = ref.tracer_u_solved[n_dmd:]
    # the pre-transport lateral tracer is not recorded; lateral motion is not transported, so it
    # equals the post-transport one
    truth_z = ref.tracer_v[n_dmd:]
    eig = np.asarray(dmd.eigs)
    out["dmd"] = dict(snapshots=n_dmd, rank=int(eig.size), max_abs_eig=float(np.abs(eig).max()),
                      rmse_x_mm=err_mm(truth_x, pred[:, :ntr]), rmse_z_mm=err_mm(truth_z, pred[:, ntr:]),
                      offline_s=t_snap + t_fit, online_s=t_on,
                      speedup_total=t_full / (t_snap + t_fit + t_on),
                      eig_real=eig.real.tolist(), eig_imag=eig.imag.tolist(),
                      scaled_mode_norms=np.asarray(dmd.scaled_mode_norms(Zp[:, -1])).tolist())
    print("DMD:", {k: v for k, v in out["dmd"].items() if not isinstance(v, list)})

    # ---------- C: multi-configuration, held-out tests ----------
    train = ["three-roller"] + [f"three-roller-t74-train{i}" for i in range(1, 7)]
    tests = [f"three-roller-t73-test{i}" for i in range(1, 7)] + [f"three-roller-a1-run{i}" for i in range(1, 13)]
    if QUICK:
        tests = tests[:2] + tests[6:8]
    n_multi = min(N_MULTI, n_full // 2)
    t0 = time.perf_counter()
    tm, snaps_pod, snaps_post, mus = [], [], [], []
    for name in train:
        mm, _ = load(name)
        _, Zp, Zq = collect_first_order(mm, jb.RunOptions(REUSE, n_multi, dt))
        tm.append(mm)
        snaps_pod.append(jnp.concatenate([Zp[:, ::2], Zq[:, ::2]], axis=1))
        snaps_post.append(Zq)
        mus.append(parameters(mm))
    t_train_runs = time.perf_counter() - t0
    Zall = jnp.concatenate(snaps_pod, axis=1)
    t_pod_fit, rom = clock(lambda: fit_reduced_pod(tm[0], Zall, dt, jb.make_solver("direct"), n_modes=40))
    X, Y, U = stack_controlled(snaps_post, [belt_inputs(mu, z.shape[1] - 1) for mu, z in zip(mus, snaps_post)])
    t_dmdc_fit, dmdc = clock(lambda: fit_dmdc(X, Y, U, rank=40))
    t_pdmd_fit, pdmd = clock(lambda: fit_parametric_dmd(snaps_post, jnp.stack(mus), rank=40))
    print(f"training runs {t_train_runs:.1f} s, fits: POD {t_pod_fit:.1f} DMDc {t_dmdc_fit:.1f} pDMD {t_pdmd_fit:.1f}")

    pod_run = jax.jit(lambda x, mu: rom.run(x, mu, n_full))
    dmdc_run = jax.jit(lambda z, mu: dmdc.predict(z, belt_inputs(mu, 1)[:, 0], n_full, observe=obs))
    pdmd_run = jax.jit(lambda mu: pdmd.predict(mu, n_full + 1, observe=obs)[1:])
    rows, t_full_tests = {}, []
    for name in tests:
        mt, _ = load(name)
        tf, (_, rf) = clock(full_run, mt, n_full, dt)
        t_full_tests.append(tf)
        mu = parameters(mt)
        st = jb.initial_state(mt)
        z0 = state_to_z(mt, st, dt)
        row = {"full_s": tf}
        xi0 = rom.project(mt, st)
        pod_run(xi0, mu)
        t_on, pr = clock(pod_run, xi0, mu)
        row["pod"] = dict(rmse_x_mm=err_mm(rf.tracer_u, pr.tracer_u), rmse_z_mm=err_mm(rf.tracer_v, pr.tracer_v),
                          online_s=t_on)
        dmdc_run(z0, mu)
        t_on, pr = clock(dmdc_run, z0, mu)
        row["dmdc"] = dict(rmse_x_mm=err_mm(rf.tracer_u, pr[:, :ntr]), rmse_z_mm=err_mm(rf.tracer_v, pr[:, ntr:]),
                           online_s=t_on)
        pdmd_run(mu)
        t_on, pr = clock(pdmd_run, mu)
        row["pdmd"] = dict(rmse_x_mm=err_mm(rf.tracer_u, pr[:, :ntr]), rmse_z_mm=err_mm(rf.tracer_v, pr[:, ntr:]),
                           online_s=t_on)
        rows[name] = row
        print(name, {k: (v if k == "full_s" else {a: round(b, 6) for a, b in v.items()}) for k, v in row.items()})
    T_full = float(np.sum(t_full_tests))
    summary = {}
    for meth, fit_s in (("pod", t_pod_fit), ("dmdc", t_dmdc_fit), ("pdmd", t_pdmd_fit)):
        ex = np.array([rows[t][meth]["rmse_x_mm"] for t in tests])
        ez = np.array([rows[t][meth]["rmse_z_mm"] for t in tests])
        on = float(np.sum([rows[t][meth]["online_s"] for t in tests]))
        summary[meth] = dict(max_rmse_x_mm=float(ex.max()), max_rmse_z_mm=float(ez.max()),
                             n_within_tol=int(np.sum(np.maximum(ex, ez) < TOL)), n_tests=len(tests),
                             offline_s=t_train_runs + fit_s, online_total_s=on,
                             speedup_online=T_full / on, speedup_total=T_full / (t_train_runs + fit_s + on))
        print(meth, summary[meth])
    out["multi"] = dict(train=train, tests=tests, train_steps=n_multi, modes=40, per_test=rows, summary=summary,
                        full_runs_total_s=T_full)
    out["source"] = {"pod_multi_total_speedup": 2.0, "dmd_total_speedup": 4.8, "dmd_rmse_scale": "~1e-8"}
    write("rom_2d_quick" if QUICK else "rom_2d", out)
    plot(out, ref, "rom_2d_quick" if QUICK else "rom_2d")


def plot(out, ref, name):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from _common import RESULTS

    fig, axs = plt.subplots(1, 3, figsize=(14, 4), constrained_layout=True)
    s = np.asarray(out["pod_single"]["singular_values"])
    axs[0].semilogy(s / s[0], ".")
    axs[0].set(title="POD singular values (t72, first steps)", xlabel="i", ylabel="σ_i / σ_0")
    ev = np.asarray(out["dmd"]["eig_real"]) + 1j * np.asarray(out["dmd"]["eig_imag"])
    w = np.asarray(out["dmd"]["scaled_mode_norms"])
    th = np.linspace(0, 2 * np.pi, 400)
    axs[1].plot(np.cos(th), np.sin(th), "k-", lw=0.5)
    sc = axs[1].scatter(ev.real, ev.imag, c=np.log10(w + 1e-300), s=10, cmap="viridis")
    fig.colorbar(sc, ax=axs[1], label="log10 ‖φ_i b_i‖")
    axs[1].set(title=f"DMD eigenvalues ({out['dmd']['snapshots']} snapshots)", aspect="equal")
    tests = out["multi"]["tests"]
    x = np.arange(len(tests))
    for k, meth in enumerate(("pod", "dmdc", "pdmd")):
        e = [max(out["multi"]["per_test"][t][meth]["rmse_x_mm"], out["multi"]["per_test"][t][meth]["rmse_z_mm"])
             for t in tests]
        axs[2].semilogy(x + 0.2 * (k - 1), e, "o", label=meth)
    axs[2].axhline(out["tol_mm"], color="k", ls="--", lw=0.8, label="0.02 mm")
    axs[2].set(title="held-out configurations (max of x/z RMSE)", xlabel="test config", ylabel="RMSE (mm)")
    axs[2].set_xticks(x, [t.replace("three-roller-", "") for t in tests], rotation=90, fontsize=7)
    axs[2].legend()
    fig.savefig(RESULTS / f"{name}.png", dpi=120)


if __name__ == "__main__":
    main()
