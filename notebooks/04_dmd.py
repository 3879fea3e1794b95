# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # 4 · Dynamic mode decomposition
#
# DMD (§5.2, §6.4, §7.4) fits a linear map `x_{k+1} ≈ A x_k` to snapshots and predicts by its
# eigen-decomposition, `x_{k₀+k} ≈ Re Σ φᵢ λᵢᵏ bᵢ`. It never looks at the equations, so the
# transport step is inside the fitted map — the source's best method: from the first 8 s (400
# snapshots) of the Table 7.2 run it predicted the remaining 92 s with an RMSE of order 1e-8 mm
# and a total speedup of **4.8** (eq. 7.5, from a per-step speedup of 7.2). The source's steps,
# and the figures this notebook puts jaxbelt's numbers beside:
#
# * eigenvalues in the complex plane coloured by the scaled mode norm ‖φᵢ bᵢ‖ (Figure 7.15);
# * modes with |λ| > 1 discarded — kept, they make the prediction blow up (Figure 7.16);
# * error against the number of snapshots (Figure 7.14), and with 10 modes (Figure 7.17);
# * the leading modes as fields (Appendix B);
# * trained on several configurations (Table 7.3's training runs) DMD fails (Figure 7.13).
#
# Snapshots are the scaled first-order states `[x; Δt ẋ]` *before* transport (the source's
# choice, §6.4). `JAXBELT_NOTEBOOK_SMALL=1` (the test suite) runs a coarse grid and 6 s.

# %%
import contextlib
import io
import json
import os
import tempfile
import time

import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np
from IPython.display import Image, display

import jaxbelt as jb
from jaxbelt import plot, rom
from jaxbelt.cli import main as jaxbelt_cli

jb.enable_x64()  # jaxbelt's results are meant in float64
SMALL = os.environ.get("JAXBELT_NOTEBOOK_SMALL") == "1"  # the test suite's quick run
N_ETA = 2 if SMALL else 18  # elements across (the source: 18 × 104, N = 3762)
STEPS = 300 if SMALL else 5000  # Δt = 0.02 s: the whole 100 s in the full notebook
SNAPSHOTS = 100 if SMALL else 400  # the source's 400 (8 s)
SNAP_COUNTS = (25, 50, 100, 200) if SMALL else (50, 100, 200, 400, 800, 1600)
MULTI_STEPS = 50 if SMALL else 200  # Table 7.3 multi-configuration test (the source: 50 + 50 snapshots, 4 s)
TOL = 0.02  # mm


def show(fig):
    """Display a figure as a compact PNG (90 dpi, tight bounding box) and close it, so that it
    is shown once and the notebook's stored outputs stay small."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    display(Image(data=buf.getvalue()))


def on_grid(name):
    sc = jb.load_scene(name)
    return sc.replace(mesh=sc.mesh.__class__(n_eta=N_ETA, n_xi=104))


# %% [markdown]
# ## One run, all the snapshots
#
# One full-order run of Table 7.2 records the pre-transport states of every step: the first
# `SNAPSHOTS` train, the rest are the truth the prediction is compared with (tracers through the
# linear tracer operator `C`, never forming fields for the prediction).

# %%
scene = on_grid("three-roller-t72")
model, DT = jb.build_model(scene), scene.time.dt  # Δt = 0.02 s
N = model.n_unknowns
reuse = jb.make_solver("direct", "reuse")
t0 = time.perf_counter()
_, Zpre, _ = jax.block_until_ready(rom.collect_first_order(model, jb.RunOptions(reuse, STEPS, DT)))
print(f"N = {N} (2N = {2 * N} per snapshot); {STEPS} steps in {time.perf_counter() - t0:.1f} s (compilation included)")
Cx, Cz = rom.tracer_operator(model, "x"), rom.tracer_operator(model, "z")
obs = jnp.concatenate([jnp.concatenate([Cx, 0 * Cx], 1), jnp.concatenate([Cz, 0 * Cz], 1)])  # tracers from z
n_tr = Cx.shape[0]
truth = (obs @ Zpre).T  # (STEPS, 2 n_tr): x then z tracers, before transport


def predict(m, fit, observe=obs):
    """Prediction of steps m+1 … STEPS from the m-th snapshot, and its RMSE over time (x, z) in mm."""
    p = fit.predict(Zpre[:, m - 1], STEPS - m, observe=observe)
    d = np.asarray(p - truth[m:])
    return p, np.sqrt(np.mean(d[:, :n_tr] ** 2, 1)) * 1e3, np.sqrt(np.mean(d[:, n_tr:] ** 2, 1)) * 1e3


# %% [markdown]
# ## Eigenvalues and the unstable modes (Figures 7.15, 7.16)

# %%
dmd = rom.fit_dmd(Zpre[:, :SNAPSHOTS])
lam = np.asarray(dmd.eigs)
w = np.asarray(dmd.scaled_mode_norms(Zpre[:, SNAPSHOTS - 1]))
stable = dmd.stable()
print(f"{SNAPSHOTS} snapshots → rank {lam.size} (every non-negligible singular value); "
      f"max |λ| = {np.abs(lam).max():.12f}; {lam.size - stable.eigs.shape[0]} mode(s) with |λ| > 1 + 1e-5")

dmd100 = rom.fit_dmd(Zpre[:, :100])
_, ex_all, ez_all = predict(100, dmd100)
_, ex_st, ez_st = predict(100, dmd100.stable())
n_unst = dmd100.eigs.shape[0] - dmd100.stable().eigs.shape[0]
fig, axs = plt.subplots(1, 2, figsize=(12, 4.8), constrained_layout=True)
plot.plot_dmd_eigenvalues(lam, w, ax=axs[0])
axs[0].set_title(f"DMD eigenvalues, {SNAPSHOTS} snapshots (Fig. 7.15)")
tt = np.arange(101, STEPS + 1) * DT
axs[1].semilogy(tt, np.maximum(ex_all, 1e-16), label=f"all modes ({n_unst} with |λ| > 1 + 1e-5)")
axs[1].semilogy(tt, np.maximum(ex_st, 1e-16), label="unstable modes discarded")
axs[1].axhline(TOL, color="r", lw=0.8, ls="--", label=f"tolerance {TOL} mm")
axs[1].set(xlabel="t [s]", ylabel="tracer RMSE (x) [mm]", title="100 snapshots: keeping vs discarding |λ| > 1 (Fig. 7.16)")
axs[1].legend(fontsize=8)
show(fig)

# %% [markdown]
# **Ours vs the source.** The eigenvalues lie inside or on the unit circle, conjugate pairs
# symmetric about the real axis; the mode with by far the largest scaled norm sits at λ = 1 — the
# steady state (the step's uniform advance and the static deflection). The source discarded
# |λ| > 1 and saw the error grow exponentially when such modes were kept (Figure 7.16). jaxbelt's
# threshold is |λ| > 1 + 1e-5, not 1: the mode that carries the static offset sits at λ = 1 to
# ~1e-6, and cutting at exactly 1 can drop it (`DMDModel.stable`). Here no mode lies beyond it,
# and the two curves coincide: jaxbelt's step with the shift transport is exactly affine in the
# state, so the fitted map has no spurious growing modes; the source's fits had several.
#
# ## Error against the number of snapshots (Figures 7.14, 7.17)

# %%
by_count = {}
for m in SNAP_COUNTS:
    if m >= STEPS:
        continue
    f = rom.fit_dmd(Zpre[:, :m]).stable()
    _, ex, ez = predict(m, f)
    by_count[m] = (int(f.eigs.shape[0]), float(np.sqrt(np.mean(ex**2))), float(np.sqrt(np.mean(ez**2))))
    print(f"{m:5d} snapshots: {by_count[m][0]:4d} stable modes, RMSE over the rest x {by_count[m][1]:.2e} mm, "
          f"z {by_count[m][2]:.2e} mm")

# 10 modes: the stable ones of largest |λ| (the source's ranking for long runs, §7.4.1)
order = np.argsort(-np.abs(np.asarray(stable.eigs)))
top10 = stable.select(order[:10])
_, ex10, ez10 = predict(SNAPSHOTS, top10)
_, ex_s, ez_s = predict(SNAPSHOTS, stable)
print(f"{SNAPSHOTS} snapshots, 10 modes of largest |λ|: RMSE x {np.sqrt(np.mean(ex10**2)):.2e} mm, "
      f"z {np.sqrt(np.mean(ez10**2)):.2e} mm (all {stable.eigs.shape[0]} stable modes: x {np.sqrt(np.mean(ex_s**2)):.2e} mm)")

fig, axs = plt.subplots(1, 2, figsize=(12, 4.2), constrained_layout=True)
ms = list(by_count)
axs[0].loglog(ms, [max(by_count[m][1], 1e-16) for m in ms], "o-", label="x (along the belt)")
axs[0].loglog(ms, [max(by_count[m][2], 1e-16) for m in ms], "s-", label="z (lateral)")
axs[0].axhline(TOL, color="r", lw=0.8, ls="--", label=f"tolerance {TOL} mm")
axs[0].set(xlabel="snapshots (first steps of the run)", ylabel="RMSE over the predicted steps [mm]",
           title="error against the number of snapshots (Fig. 7.14)")
axs[0].legend(fontsize=8)
axs[0].grid(alpha=0.3, which="both")
tt = np.arange(SNAPSHOTS + 1, STEPS + 1) * DT
plot.plot_rmse_over_time(tt, ex10 * 1e3, TOL * 1e3, ax=axs[1])  # µm
axs[1].semilogy(tt, np.maximum(ez10, 1e-16), lw=1, color="tab:green", label="z")
axs[1].legend(fontsize=8)
axs[1].set_title(f"{SNAPSHOTS} snapshots, 10 modes: RMSE over time (Fig. 7.17)")
show(fig)

# %% [markdown]
# **Ours vs the source.** The source found that *fewer* snapshots could be more accurate (with
# all modes kept) and settled on 400 because by eye the start-up was over by 8 s; its 10-mode
# model stayed within 20 µm, with an RMSE of order 1e-8 mm. Here more snapshots are never worse:
# 50 already predict the remaining 4950 steps to ~1e-4 mm, 400 to ~1e-9 mm — the rank stops
# growing at ~26, the number of modes the (exactly affine) step has in these data. Ten modes of
# largest |λ| give the same error as all of them: the others have |λ| ≪ 1 and have decayed by the
# end of the training window. The count can also be chosen from the data
# (`jaxbelt.rom.calibration.snapshot_count`) instead of by eye.
#
# ## The leading modes as fields (Appendix B)
#
# The real part of a mode is a displacement field; `plot_fields` draws it over the unrolled belt
# (a stand-in "trajectory" whose frames are modes).

# %%
from types import SimpleNamespace

w_st = np.asarray(stable.scaled_mode_norms(Zpre[:, SNAPSHOTS - 1]))
lam_st = np.asarray(stable.eigs)
pick = [i for i in np.argsort(-w_st) if lam_st[i].imag >= 0][:3]  # one of each conjugate pair
phi = np.asarray(stable.modes)[: model.n_xi * model.block, pick].real.T
phi /= 1e3 * np.abs(phi).max(axis=1, keepdims=True)  # each mode to max 1 on the colour bars (drawn ×1e3 as mm)
frames = SimpleNamespace(t=np.arange(len(pick), dtype=float), u=phi.reshape(len(pick), model.n_xi, model.block))
axes = plot.plot_fields(model, frames, times=list(frames.t))
for r, i in enumerate(pick):
    for c, comp in enumerate(("x", "z")):
        axes[r, c].set_title(f"mode {r + 1} ({comp} part, scaled): λ = {lam_st[i].real:.5f} "
                             f"{'+' if lam_st[i].imag >= 0 else '−'} {abs(lam_st[i].imag):.5f}i", fontsize=9)
show(axes[0, 0].figure)

# %% [markdown]
# ## Total speedup (eq. 7.5)
#
# The source's speedup counts steps: 400 full steps, then 4600 DMD steps each 7.2× cheaper,
# 5000 / (400 + 4600 / 7.2) ≈ 4.8. jaxbelt's `jaxbelt reduce` measures wall time instead: the
# whole run in the *fastest* full mode that reproduces the scene's own (here the reuse mode,
# every variant compiled first) against offline (the 400 snapshot steps + the fit) plus online
# (the prediction), and prints the eq. 7.5 figure beside it. Run here through the CLI's entry
# point on a variant file of the scene:

# %%
with tempfile.TemporaryDirectory() as tmp:
    variant = os.path.join(tmp, "t72.toml")
    with open(variant, "w") as fh:
        fh.write(f'extends = "three-roller-t72"\n[mesh]\nn_eta = {N_ETA}\nn_xi = 104\n'
                 f'[time]\nt_end_s = {STEPS * DT}\n[solver]\nlinear_solver = "reuse"\n')
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = jaxbelt_cli(["reduce", variant, "--method", "dmd", "--train-steps", str(SNAPSHOTS),
                            "--stride", "0", "--json"])
assert code == 0
rep = json.loads(buf.getvalue())
tm = rep["timings"]
print(f"jaxbelt reduce (DMD, {rep['train_steps']} snapshots, {rep['modes']} modes): RMSE {rep['rmse_um']:.3g} µm")
print(f"full run {tm['full_run_s']:.2f} s ({tm['full_mode']}); offline {tm['offline_s']:.2f} s, online {tm['online_s']:.3f} s")
print(f"speedup online ×{tm['speedup_online']:.0f}, per step ×{tm['speedup_per_step_online']:.0f}; "
      f"total ×{tm['speedup_total']:.1f} (eq. 7.5: ×{tm['speedup_eq_7_5']:.1f}); source: ×7.2 per step, ×4.8 total")

# %% [markdown]
# **Ours vs the source.** The prediction's per-step speedup is in the hundreds (×350–450 in the
# full-size runs) — a DMD step on the tracers is a few complex multiplies per mode — where the
# source's was 7.2, because its DMD produced full states. The total is then bounded by the snapshot
# run: eq. 7.5 gives n / (n_train + …) ≈ 12 for 400 of 5000 steps. The wall-time figure is lower
# (×5–6 in the full-size runs, the source's ×4.8 by a different count) because the offline part costs
# more than its 400 steps' share of the full run: the snapshot run records every pre-transport
# state (2N × 400 values) and the SVD of that matrix adds to it. The source's ×4.8 was a step
# count against its own MATLAB model; the figure here is measured against jaxbelt's fastest full
# mode, compilation excluded on both sides, on a shared 2-core machine.
#
# ## Trained on several configurations, DMD fails (Figure 7.13)
#
# The source stacked the snapshots of Table 7.3's two training runs (eq. 6.12–6.13, 100
# snapshots) and predicted test run 1 from its initial state: "entirely different". The same
# here, with `stack_trajectories`:

# %%
names = ["three-roller-t73-train1", "three-roller-t73-train2", "three-roller-t73-test1"]
chis = jnp.stack([jb.build_model(on_grid(n)).chi_static for n in names])


def first_order_run(chi):
    return rom.collect_first_order(model.replace(chi_static=chi), jb.RunOptions(reuse, MULTI_STEPS, DT))[1]


Zs = jax.vmap(first_order_run)(chis)  # (3, 2N, MULTI_STEPS), one compiled batch
X, Y = rom.stack_trajectories([Zs[0], Zs[1]])
multi = rom.fit_dmd(X, Y).stable()
p = multi.predict(Zs[2][:, 0], MULTI_STEPS - 1, observe=obs)
d = np.asarray(p - (obs @ Zs[2][:, 1:]).T)
half = MULTI_STEPS // 2
own = rom.fit_dmd(Zs[2][:, :half]).stable()  # for scale: DMD on test run 1's own first half
d_own = np.asarray(own.predict(Zs[2][:, half - 1], MULTI_STEPS - half, observe=obs) - (obs @ Zs[2][:, half:]).T)
v_test = np.asarray(obs @ Zs[2])[n_tr:]
print(f"test run 1, {MULTI_STEPS * DT:g} s, lateral (z) tracers: response up to {np.abs(v_test).max() * 1e3:.3g} mm")
print(f"  multi-configuration DMD ({X.shape[1]} snapshot pairs of the 2 training runs): "
      f"RMSE z {np.sqrt(np.mean(d[:, n_tr:] ** 2)) * 1e3:.3g} mm, x {np.sqrt(np.mean(d[:, :n_tr] ** 2)) * 1e3:.3g} mm")
print(f"  DMD of the test run's own first {half} steps: RMSE z {np.sqrt(np.mean(d_own[:, n_tr:] ** 2)) * 1e3:.2g} mm, "
      f"x {np.sqrt(np.mean(d_own[:, :n_tr] ** 2)) * 1e3:.2g} mm")

fig, ax = plt.subplots(figsize=(8, 3.2), constrained_layout=True)
xt = np.asarray(jb.build_mesh(scene).tracer_x) * 1e3
o = np.argsort(xt)
ax.plot(xt[o], v_test[o, -1] * 1e3, "o-", ms=3, label="full model")
ax.plot(xt[o], np.asarray(p)[-1, n_tr:][o] * 1e3, "s--", ms=3, label="multi-configuration DMD")
ax.set(xlabel="tracer position along the belt [mm]", ylabel="v [µm]",
       title=f"test run 1: lateral tracer displacement at t = {MULTI_STEPS * DT:g} s (Fig. 7.13)")
ax.legend(fontsize=8)
show(fig)

# %% [markdown]
# A single linear map `A` fitted to two configurations cannot know which configuration a new
# start state belongs to: the misalignment enters the belt's step as a constant forcing, which
# plain DMD must fold into `A`. The error is of the size of the response itself — the source's
# Figure 7.13 conclusion holds. Notebook 5 gives the map the misalignments as an input (DMD with
# control) and interpolates per-configuration DMDs (parametric DMD), the two remedies the source
# proposed for future research.
