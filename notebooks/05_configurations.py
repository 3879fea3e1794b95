# ---
# jupyter:
#   jupytext:
#     formats: ipynb,py:percent
#     text_representation:
#       extension: .py
#       format_name: percent
#       format_version: '1.3'
#       jupytext_version: 1.19.6
#   kernelspec:
#     display_name: Python 3 (ipykernel)
#     language: python
#     name: python3
# ---

# %% [markdown]
# # 5 · Several configurations: one reduced model, held-out misalignments
#
# The point of a reduced model for tolerance work is to run configurations it was *not* trained
# on. The source (§7.3.2, Appendix A) trained POD on the six one-component runs of Table 7.4,
# kept 108 modes and tested on the twelve configurations of Table A.1 — all below its 0.02 mm
# tolerance, runs 4 and 5 the worst, run 11 (roller 2 tilted five times beyond the training)
# still fine — for a total speedup of **2.0**. Its DMD trained on several configurations failed
# (§6.4.2, §7.4; notebook 4), and it named DMD with control and parametric DMD as future work.
#
# jaxbelt trains three models on the nominal machine plus the six Table 7.4 runs:
#
# * the **fully reduced POD** step, the misalignments an explicit input `μ` (`fit_reduced_pod`);
# * **DMD with control**, inputs `[μ; 1]` (`fit_dmdc`);
# * **parametric DMD**, one DMD per training run interpolated in μ (`fit_parametric_dmd`),
#   its trajectories started after the start-up step (the static initial state is not on the
#   low-rank dynamics that follow; `jaxbelt.rom.dmdc`);
#
# tests them on Table A.1's twelve runs and Table 7.3's six test runs, and asks the residual
# **error indicator** what it would have said without the full runs. `JAXBELT_NOTEBOOK_SMALL=1`
# (the test suite) uses 2 elements across and short runs.

# %%
import io
import os
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np
from IPython.display import Image, display

import jaxbelt as jb
from jaxbelt import plot, rom
from jaxbelt.rom.error_estimate import error_rom, residual_indicator

jb.enable_x64()  # jaxbelt's results are meant in float64
SMALL = os.environ.get("JAXBELT_NOTEBOOK_SMALL") == "1"  # the test suite's quick run
N_ETA = 2 if SMALL else 18  # elements across (the source: 18 × 104, N = 3762)
TRAIN = 50 if SMALL else 200  # steps per training run (the source: 50; the lateral response settles in ~4 s)
TEST = 100 if SMALL else 1000  # steps per held-out test run (20 s in the full notebook)
RANK = 20 if SMALL else 40  # modes of every reduced model
STRIDE = 1 if SMALL else 4  # DMDc / parametric DMD: a map over STRIDE steps, fitted on every STRIDE-th state
POD_STRIDE = 1 if SMALL else 2  # POD: every POD_STRIDE-th snapshot (the SVD of 2N × all of them is the fit's cost)
TOL = 0.02  # mm


def show(fig):
    """Display a figure as a compact PNG (90 dpi, tight bounding box) and close it, so that it
    is shown once and the notebook's stored outputs stay small."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    display(Image(data=buf.getvalue()))


# %% [markdown]
# ## The configurations
#
# Every scene here is the `three-roller` machine with other roller misalignments, so one
# compiled model serves them all: a configuration is its `chi_static` (read from the built-in
# Table 7.x scene files), and the full-order runs of all of them go in one `vmap` batch.

# %%
sc = jb.load_scene("three-roller")
base = jb.build_model(sc.replace(mesh=sc.mesh.__class__(n_eta=N_ETA, n_xi=104)))
DT = sc.time.dt  # Δt = 0.02 s, the time step of every run here
N = base.n_unknowns
reuse = jb.make_solver("direct", "reuse")


def configuration(name):
    """The misalignment (chi_static) of a built-in scene, on this grid."""
    rollers = jb.load_scene(name).rollers
    return jb.with_misalignment(base, translation=jnp.array([r.translation for r in rollers]),
                                rotation=jnp.array([r.rotation for r in rollers])).chi_static


train_names = ["three-roller"] + [f"three-roller-t74-train{i}" for i in range(1, 7)]
test_names = [f"three-roller-a1-run{i}" for i in range(1, 13)] + [f"three-roller-t73-test{i}" for i in range(1, 7)]
chi_train = jnp.stack([configuration(n) for n in train_names])
chi_test = jnp.stack([configuration(n) for n in test_names])
labels = [n.replace("three-roller-", "").replace("a1-run", "A.1 run ").replace("t73-test", "7.3 test ") for n in test_names]
print(f"N = {N}; {len(train_names)} training configurations, {len(test_names)} held-out ones")


def first_order_run(chi, n):
    return rom.collect_first_order(base.replace(chi_static=chi), jb.RunOptions(reuse, n, DT))


# the axial design of the last section: the aligned machine and each component the test runs vary
# (Table 7.4's six and roller 3's x translation) at ± its half-width (5 mm / 0.5 mrad), run in the
# same batch as the Table 7.4 design
axial_components = ["roller 1:dx", "roller 1:dy", "roller 2:ax", "roller 2:ay", "roller 3:ax", "roller 3:dy",
                    "roller 3:dx"]
half = np.array([5.0 if c.split(":")[1].startswith("d") else 0.5 for c in axial_components])  # mm / mrad
axial_models, _, space = rom.axial_design(base, axial_components, half)
chi_axial = jnp.stack([m.chi_static for m in axial_models])

t0 = time.perf_counter()
_, Zpre_all, Zpost_all = jax.block_until_ready(jax.vmap(lambda c: first_order_run(c, TRAIN))(
    jnp.concatenate([chi_train, chi_axial])))
n_t = len(train_names)
Zpre, Zpost, Zax = Zpre_all[:n_t], Zpost_all[:n_t], Zpost_all[n_t:]
t_train = (time.perf_counter() - t0) * n_t / (n_t + len(chi_axial))  # the Table 7.4 design's share
print(f"training runs: {n_t} (Table 7.4 design) + {len(chi_axial)} (axial design) × {TRAIN} steps in "
      f"{time.perf_counter() - t0:.1f} s (one vmap batch, compilation included)")

# %% [markdown]
# ## Three reduced models from the same runs

# %%
mu_train = jax.vmap(lambda c: rom.parameters(base.replace(chi_static=c)))(chi_train)
t0 = time.perf_counter()
snaps = [jnp.concatenate([Zpre[j], Zpost[j]], 1)[:, ::POD_STRIDE] for j in range(len(chi_train))]
pod = rom.fit_reduced_pod(base, jnp.concatenate(snaps, 1), dt=DT, n_modes=RANK)  # linearised at the nominal machine
t_pod = time.perf_counter() - t0
post = [Zpost[j][:, ::STRIDE] for j in range(len(chi_train))]
X, Y, U = rom.stack_controlled(post, [rom.belt_inputs(mu, z.shape[1] - 1) for mu, z in zip(mu_train, post)])
t0 = time.perf_counter()
dmdc = jax.block_until_ready(rom.fit_dmdc(X, Y, U, rank=RANK))
t_dmdc = time.perf_counter() - t0
t0 = time.perf_counter()
# trajectories from the first STRIDE step on (z_S, z_2S, …), not from the static initial state z_0
pdmd = jax.block_until_ready(rom.fit_parametric_dmd([z[:, 1:] for z in post], mu_train, rank=RANK))
t_pdmd = time.perf_counter() - t0
pdmd_z0 = rom.fit_parametric_dmd(post, mu_train, rank=RANK)  # the same, started at z_0: for comparison
print(f"fits: POD {t_pod:.1f} s (SVD + projection, compilation included), DMDc {t_dmdc:.1f} s, parametric DMD {t_pdmd:.1f} s")

# %% [markdown]
# ## The held-out runs
#
# Full-order runs of the 18 test configurations (one batch) against the three models'
# predictions from each configuration's initial state — the reduced models take only `μ`.

# %%
Cx, Cz = rom.tracer_operator(base, "x"), rom.tracer_operator(base, "z")
obs = jnp.concatenate([jnp.concatenate([Cx, 0 * Cx], 1), jnp.concatenate([Cz, 0 * Cz], 1)])
n_tr = Cx.shape[0]


# the model, the integrator and the reduced models are arguments, not closed-over constants: XLA
# would otherwise fold their arrays into the program (slow to compile, large to keep)
@eqx.filter_jit
def full_tracers(m, integ, chis):
    def one(chi):
        _, tr = jb.simulate(m.replace(chi_static=chi), integ, n_steps=TEST, dt=DT, check=False)
        return jnp.concatenate([tr.tracer_u, tr.tracer_v], 1)  # (TEST, 2 n_tr)

    return jax.vmap(one)(chis)


@eqx.filter_jit
def reduced_tracers(m0, models, obs, chis):
    pod, dmdc, pdmd, pdmd_z0 = models

    def one(chi):
        m = m0.replace(chi_static=chi)
        st, mu = jb.initial_state(m), rom.parameters(m)
        out = pod.run(pod.project(m, st), mu, TEST)
        p_pod = jnp.concatenate([out.tracer_u, out.tracer_v], 1)
        p_dmdc = dmdc.predict(rom.state_to_z(m, st, dt=DT), rom.belt_inputs(mu, 1)[:, 0], TEST // STRIDE, observe=obs)
        p_pdmd = pdmd.predict(mu, TEST // STRIDE, observe=obs)  # k = 0 is step STRIDE
        p_pdmd_z0 = pdmd_z0.predict(mu, TEST // STRIDE + 1, observe=obs)[1:]  # k = 0 is the initial state
        return {"POD": p_pod, "DMDc": p_dmdc, "parametric DMD": p_pdmd, "parametric DMD from z_0": p_pdmd_z0}

    return jax.vmap(one)(chis)


t0 = time.perf_counter()
truth = jax.block_until_ready(full_tracers(base, reuse, chi_test))
t_full = time.perf_counter() - t0
jax.block_until_ready(reduced_tracers(base, (pod, dmdc, pdmd, pdmd_z0), obs, chi_test))  # compile
t0 = time.perf_counter()
pred = jax.block_until_ready(reduced_tracers(base, (pod, dmdc, pdmd, pdmd_z0), obs, chi_test))
pred_z0 = pred.pop("parametric DMD from z_0")
t_online = time.perf_counter() - t0
print(f"full runs: {len(test_names)} × {TEST} steps in {t_full:.1f} s (compilation included); "
      f"all reduced predictions {t_online:.3f} s")

sel = {"POD": slice(None), "DMDc": slice(STRIDE - 1, None, STRIDE), "parametric DMD": slice(STRIDE - 1, None, STRIDE)}
err = {}  # method -> (tests, 2): RMSE x, z in mm
for meth, p in pred.items():
    d = np.asarray(p) - np.asarray(truth)[:, sel[meth]][:, : p.shape[1]]
    err[meth] = np.stack([np.sqrt(np.mean(d[..., :n_tr] ** 2, (1, 2))), np.sqrt(np.mean(d[..., n_tr:] ** 2, (1, 2)))], 1) * 1e3
tv = np.asarray(truth)
scale = np.stack([np.sqrt(np.mean(tv[..., :n_tr] ** 2, (1, 2))), np.sqrt(np.mean(tv[..., n_tr:] ** 2, (1, 2)))], 1) * 1e3
# RRMSE (eq. 6.2, the source's Figures A.1, A.2); undefined (nan) where a run has no response in a direction
rrmse_pod = np.where(scale > 1e-6, err["POD"] / np.maximum(scale, 1e-300), np.nan)

print(f"{'test':13s} " + " ".join(f"{m:>22s}" for m in err) + f"   {'POD RRMSE x, z':>18s}")
print(f"{'':13s} " + " ".join(f"{'x [mm]':>11s}{'z [mm]':>11s}" for _ in err))
for i, lab in enumerate(labels):
    print(f"{lab:13s} " + " ".join(f"{err[m][i, 0]:11.2e}{err[m][i, 1]:11.2e}" for m in err)
          + f"   {rrmse_pod[i, 0]:8.1e} {rrmse_pod[i, 1]:8.1e}")
d0 = np.asarray(pred_z0) - np.asarray(truth)[:, sel["parametric DMD"]]
err_z0 = np.stack([np.sqrt(np.mean(d0[..., :n_tr] ** 2, (1, 2))), np.sqrt(np.mean(d0[..., n_tr:] ** 2, (1, 2)))], 1) * 1e3
a1 = slice(0, 12)
print(f"parametric DMD trained from the initial state z_0 instead: worst {err_z0[a1].max():.2e} mm on Table A.1 "
      f"(from z_{STRIDE}: {err['parametric DMD'][a1].max():.2e} mm)")
for meth in err:
    ok = np.max(err[meth], 1) < TOL
    print(f"{meth:15s}: Table A.1 within {TOL} mm: {ok[a1].sum()}/12 (worst {err[meth][a1].max():.2e} mm); "
          f"Table 7.3 tests: {ok[12:].sum()}/6 (worst {err[meth][12:].max():.2e} mm)")

# %%
fig, axs = plt.subplots(1, 2, figsize=(14, 4.2), constrained_layout=True, sharey=True)
xi = np.arange(len(labels))
for c, comp in enumerate(("x (along the belt)", "z (lateral)")):
    for k, meth in enumerate(err):
        axs[c].bar(xi + (k - 1) * 0.27, np.maximum(err[meth][:, c], 1e-12), 0.27, label=meth)
    axs[c].axhline(TOL, color="r", lw=0.8, ls="--", label=f"tolerance {TOL} mm")
    axs[c].axvline(11.5, color="0.4", lw=0.8)
    axs[c].set_yscale("log")
    axs[c].set_xticks(xi, labels, rotation=60, ha="right", fontsize=8)
    axs[c].set_title(f"tracer RMSE, {comp}, over {TEST * DT:g} s")
axs[0].set_ylabel("RMSE [mm]")
axs[1].legend(fontsize=8)
show(fig)

# %% [markdown]
# **Ours vs the source.**
#
# * *Table A.1* (the source's Figures 7.11, A.1, A.2): the fully reduced POD and DMDc predict
#   every run within the tolerance with 40 modes where the source's POD needed 108 — the
#   misalignments enter the reduced step as an input (`B μ`, projected from the full step's
#   Jacobian), so a configuration outside the training's *range* (run 4: 12.5 mm, 2.5× the
#   training; run 11: 5×) costs nothing: the step is affine in μ.
# * *Table 7.3 tests*: they move roller 3 along x, a direction **no Table 7.4 run varied**. The
#   source's rule (§7.3.2: "the testing data must include the same misalignments as the training
#   data") forbids exactly this; here the models miss it by far more than the tolerance: a reduced
#   model cannot extrapolate to a direction it has never seen.
# * *Parametric DMD* predicts Table A.1 within the tolerance too, once its trajectories start
#   after the start-up step; trained from the static initial state z_0 it misses by orders of
#   magnitude (printed above): the step out of the static state is not on the low-rank dynamics
#   that follow, and a per-configuration DMD fitted through it forecasts even its own
#   configuration badly (`jaxbelt.rom.dmdc`). Both remedies the source proposed work.
#
# The speedup over these runs, as the source's (the full runs the models replace against the
# training runs, the fits and every reduced prediction; compilation included in the full batch
# and the fits, which favours the full model):

# %%
offline = t_train + t_pod + t_dmdc
print(f"full: {t_full:.1f} s for {len(test_names)} runs of {TEST} steps (one vmap batch); "
      f"reduced: offline {offline:.1f} s (training {t_train:.1f} s + POD fit {t_pod:.1f} s + DMDc fit {t_dmdc:.1f} s) "
      f"+ online {t_online:.3f} s")
print(f"total speedup ×{t_full / (offline + t_online):.2f} for these {len(test_names)} configurations "
      f"(source, POD on Table A.1: ×2.0); the online part alone ×{t_full / t_online:.0f}")

# %% [markdown]
# For 18 configurations the total is below one: the offline part — mostly the POD fit (the SVD
# of the snapshots and the projection of the step) — costs more than 18 full runs in one `vmap`
# batch. The online part alone is two orders of magnitude faster, so the models pay off from
# some tens of configurations on — what a tolerance sweep over hundreds or thousands needs
# (notebook 6). The source's ×2.0 was a step count against sequential runs of its own model.
#
# ## What the error estimate says
#
# Without the full runs, how would one know which predictions to trust? Two estimates from the
# full-order one-step residuals of the reduced trajectory (lifted to full states), neither needing
# a reference run. The **error ROM** (`jaxbelt.rom.error_estimate.error_rom`, what `jaxbelt reduce`
# reports as `error_estimate_um`) propagates window means of the residuals through the full
# step's Jacobian in a small residual-enriched subspace; the simpler **triangle-inequality
# indicator** (`residual_indicator`) only accumulates the tracer residual of every `stride`-th
# step. Here both, raw (no safety factor), for POD on held-out runs:

# %%
picks = [labels.index("A.1 run 4"), labels.index("A.1 run 11"), labels.index("7.3 test 2")]
picks = picks[::2] if SMALL else picks  # each estimate compiles one full step of its configuration
stride = 10
fig, axs = plt.subplots(1, len(picks), figsize=(15, 3.8), constrained_layout=True)
tt = np.arange(1, TEST + 1) * DT
for ax, i in zip(axs, picks):
    m = base.replace(chi_static=chi_test[i])
    st = jb.initial_state(m)
    xi0 = pod.project(m, st)
    out = pod.run(xi0, rom.parameters(m), TEST)
    coords = jnp.concatenate([xi0[None], out.xi])
    est = error_rom(m, pod.basis, coords, dt=DT, z_true0=rom.state_to_z(m, st, dt=DT), stride=stride, solver=reuse)
    ind = residual_indicator(m, pod.fields(coords), dt=DT, stride=stride, solver=reuse)
    e_t = np.sqrt(np.mean((np.asarray(truth[i, :, :n_tr]) - np.asarray(out.tracer_u)) ** 2, 1)) * 1e3
    plot.plot_rmse_over_time(tt, e_t * 1e3, TOL * 1e3, estimate_um=np.asarray(est.error_um), ax=ax,  # µm
                             estimate_label="error ROM estimate")
    ax.semilogy((np.asarray(ind.step) + 1) * DT, np.asarray(ind.estimate_um), "x:", ms=3, lw=1,
                color="tab:gray", label="triangle-inequality indicator")
    ax.legend(fontsize=8)
    ax.set_title(f"POD, {labels[i]}", fontsize=9)
    true_rmse = float(np.sqrt(np.mean(e_t**2)))
    est_mm, est_max_mm, ind_end_mm = est.rmse_um / 1e3, est.max_um / 1e3, float(ind.estimate_um[-1]) / 1e3
    print(f"{labels[i]:11s}: true RMSE {true_rmse:.2e} mm (max over time {e_t.max():.2e}); error ROM "
          f"{est_mm:.2e} mm (×{est_mm / true_rmse:.2f}, max ×{est_max_mm / e_t.max():.2f}, "
          f"{est.cost.full_step_equivalents} full-step equivalents for {TEST} steps); triangle inequality "
          f"{ind_end_mm:.2e} mm at the end (×{ind_end_mm / e_t[-1]:.0f})")
show(fig)

# %% [markdown]
# The error ROM follows the true error over time; the ratios printed are its raw effectivities
# (estimate / true error). `jaxbelt reduce` multiplies it by a safety factor calibrated on the
# training data alone (the same fit on half the training window predicting the training runs'
# second halves), measured 1–3× the true error on held-out configurations
# (`benchmarks/rom_indicator.py`, README "Reduced models"). The triangle-inequality indicator sums
# residuals whose effects partly cancel and decay; it errs high by one to two orders of magnitude
# and against the 0.02 mm tolerance flags even the good runs — a ranking, not an estimate.
#
# ## The remedy: train on every direction (the axial design)
#
# The response is linear in small misalignments, so the responses to each component alone span
# the response to any combination: the aligned machine plus each component at ± its half-width
# (`jaxbelt.rom.axial_design`) trains one model for the whole box of those components. Here the
# seven components the test runs vary — Table 7.4's six and roller 3's x translation — give 15
# runs (they went in the first batch); `jaxbelt reduce --train-ranges` does the same over any box.

# %%
t0 = time.perf_counter()
post_ax = [Zax[j][:, ::STRIDE] for j in range(len(chi_axial))]
mu_ax = jax.vmap(lambda c: rom.parameters(base.replace(chi_static=c)))(chi_axial)
X, Y, U = rom.stack_controlled(post_ax, [rom.belt_inputs(mu, z.shape[1] - 1) for mu, z in zip(mu_ax, post_ax)])
dmdc_ax = rom.fit_dmdc(X, Y, U, rank=RANK)
print(f"axial design ({len(chi_axial)} runs × {TRAIN} steps, run with the Table 7.4 design above): "
      f"DMDc fit in {time.perf_counter() - t0:.1f} s")


@eqx.filter_jit
def dmdc_predictions(m0, model, obs, chis):
    def one(chi):
        m = m0.replace(chi_static=chi)
        mu = rom.parameters(m)
        return model.predict(rom.state_to_z(m, jb.initial_state(m), dt=DT), rom.belt_inputs(mu, 1)[:, 0], TEST // STRIDE,
                             observe=obs)

    return jax.vmap(one)(chis)


d = np.asarray(dmdc_predictions(base, dmdc_ax, obs, chi_test)) - np.asarray(truth)[:, sel["DMDc"]]
err_ax = np.stack([np.sqrt(np.mean(d[..., :n_tr] ** 2, (1, 2))), np.sqrt(np.mean(d[..., n_tr:] ** 2, (1, 2)))], 1) * 1e3
for i in range(12, len(labels)):
    print(f"{labels[i]:11s}: DMDc on Table 7.4 x {err['DMDc'][i, 0]:.2e} / z {err['DMDc'][i, 1]:.2e} mm  →  "
          f"on the axial design x {err_ax[i, 0]:.2e} / z {err_ax[i, 1]:.2e} mm")
print(f"axial-design DMDc: {np.sum(np.max(err_ax, 1) < TOL)}/{len(labels)} held-out runs within {TOL} mm "
      f"(worst {err_ax.max():.2e} mm)")

# %% [markdown]
# **Summary (ours vs the source).** The source's POD on Table 7.4 met the tolerance on Table A.1
# with 108 modes for a ×2.0 total speedup, and multi-configuration DMD failed. Here the fully
# reduced POD, DMDc and parametric DMD (its trajectories started after the start-up step) meet it
# on Table A.1 with 40 modes; no model trained on Table 7.4 predicts Table 7.3's tests, which move
# a component the training never varied; the residual indicator ranks the runs as their true
# errors do, though it errs high by one to two orders of magnitude; and training on every
# direction the tests vary (the axial design) fixes the Table 7.3 tests — 18 of 18 held-out runs
# within the tolerance with DMDc.
