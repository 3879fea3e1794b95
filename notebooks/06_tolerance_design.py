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
# # 6 · Tolerance design: sensitivities, the tolerance box, the yield, belt walk
#
# The source's research question is how to "enable faster detection of issues arising from
# manufacturing imperfections", with an accuracy tolerance of **20 µm** in both directions
# (§2); it stops at fast reduced models. jaxbelt goes on to the design question itself: *which
# roller tolerances keep the belt within 20 µm, and what will the yield be?* Everything here is
# differentiable end to end — `jax.grad` through the whole run (solve + transport, `lax.scan`),
# forward-mode Jacobians for the tolerance box, `vmap` batches for Monte Carlo. The source has no
# tolerance figures or tables to set beside these; where it has a counterpart (its lateral model
# without belt walk) it is said below.
#
# 1. one tilt, one tolerance: `jax.grad` + `optax`;
# 2. the sensitivities of the lateral deviation to all 15 roller components;
# 3. the largest tolerance box, verified by full runs;
# 4. the yield under random misalignments: Monte Carlo, FORM, importance sampling;
# 5. belt walk on a skewed roller, against an independent beam theory.
#
# `JAXBELT_NOTEBOOK_SMALL=1` (the test suite) runs coarse grids and short runs.

# %%
import io
import os
import tempfile
import time

import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np
import optax
from IPython.display import Image, display

import jaxbelt as jb
from jaxbelt import design, lateral_theory, plot

jb.enable_x64()  # jaxbelt's results are meant in float64
SMALL = os.environ.get("JAXBELT_NOTEBOOK_SMALL") == "1"  # the test suite's quick run
N_ETA, STEPS = (2, 9) if SMALL else (3, 40)  # section 1: a coarsened three-roller, few steps
DESIGN_ETA = 2 if SMALL else 6  # sections 2-4: elements across the design scene (its own: 18)
T_EVAL = 0.98 if SMALL else 4.0  # s: the lateral response has settled by 4 s (three-roller-tolerance)
SAMPLES = 32 if SMALL else 200  # Monte-Carlo configurations
WALK_ETA = 2 if SMALL else 9  # section 5: elements across, and the grids along (n_xi, Δt) with the run length
WALK_GRIDS, WALK_T = (((104, 0.02),), 2.0) if SMALL else (((104, 0.02), (208, 0.01)), 20.0)
LIMIT_UM = 20.0
tmp = tempfile.mkdtemp()


def show(fig):
    """Display a figure as a compact PNG (90 dpi, tight bounding box) and close it, so that it
    is shown once and the notebook's stored outputs stay small."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    plt.close(fig)
    display(Image(data=buf.getvalue()))


def show_png(name, draw, *args):
    """Display a figure that a jaxbelt.plot function writes to a file."""
    path = os.path.join(tmp, name)
    draw(*args, path)
    display(Image(filename=path, width=820))


# %% [markdown]
# ## 1 · How far may roller 2 tilt before the belt moves 20 µm sideways?
#
# The built-in `three-roller` scene (coarsened across the width for speed), roller 2 tilted about
# x by α; the measure is the lateral tracer displacement after the start-up (RMS over the
# tracers). `jax.grad` gives its sensitivity to α through the whole simulation, and `optax`
# finds the tilt at which the displacement reaches the tolerance.

# %%
scene = jb.load_scene("three-roller")
scene = scene.replace(mesh=scene.mesh.__class__(n_eta=N_ETA, n_xi=104))
model, DT = jb.build_model(scene), scene.time.dt  # Δt = 0.02 s
print(model.n_unknowns, "unknowns")


def lateral_drift_mm(alpha):
    rot = jnp.zeros((3, 3)).at[1, 0].set(alpha)
    _, tr = jb.simulate(jb.with_misalignment(model, rotation=rot), n_steps=STEPS, dt=DT,
                        adjoint=jb.Checkpointed(steps=0))  # a short run: no checkpointed chunks
    v = tr.tracer_v[-1] * 1e3
    return jnp.sqrt(jnp.mean(v**2))  # RMS over the tracers at the end, mm


drift_and_grad = jax.jit(jax.value_and_grad(lateral_drift_mm))  # compiled once, used below too
alpha0 = jnp.asarray(1e-4, dtype=float)  # not weakly typed, as the optimiser's iterates: one program
d0, g0 = drift_and_grad(alpha0)
print(f"drift at {alpha0 * 1e3:.2f} mrad: {float(d0) * 1e3:.3f} µm, sensitivity {float(g0):.3f} mm/rad")

# %%
TOL_MM = LIMIT_UM * 1e-3
# less momentum than Adam's default b1 = 0.9, which orbits the minimum of this one-parameter loss
# for ~100 iterations; with b1 = 0.5 the drift is on the tolerance (to 0.01 µm) after ~25
opt = optax.adam(1e-4, b1=0.5)
update = jax.jit(opt.update)
alpha = alpha0
state = opt.init(alpha)
for i in range(60):
    d, g = drift_and_grad(alpha)
    # the loss ((d - TOL) / TOL)², its gradient by the chain rule through the drift's
    updates, state = update(2 * (d - TOL_MM) / TOL_MM**2 * g, state, alpha)
    alpha = optax.apply_updates(alpha, updates)
drift, _ = drift_and_grad(alpha)
print(f"tolerated tilt of roller 2 about x: {float(alpha) * 1e3:.3f} mrad "
      f"(drift {float(drift) * 1e3:.2f} µm)")
linear_estimate = TOL_MM / float(g0)
print(f"linear estimate from the sensitivity alone: {linear_estimate * 1e3:.3f} mrad")

# %% [markdown]
# The optimiser and the linear estimate agree: the drift is linear in the tilt (to ~1e-9 on
# these scales; README "linearity"), which is what makes the tolerance box below a linear
# problem checked by full runs.
#
# ## 2 · Sensitivities of the lateral deviation to every roller component
#
# The source's variant `three-roller-tolerance` (no belt walk; notebook 7 asks the question of
# the steered machine, the command line's default) is the aligned machine evaluated at 4 s, when the
# lateral response has settled. A *study* fixes the metric — here `lateral_max`, the largest
# lateral deviation of a tracer from the aligned machine's, µm — and runs the aligned reference
# once. At the aligned machine every metric sits at its kink (a norm of a zero response), so the
# report gives the one-sided slopes from the forward-mode Jacobian.

# %%
dscene = jb.load_scene("three-roller-tolerance")
dscene = dscene.replace(mesh=dscene.mesh.__class__(n_eta=DESIGN_ETA, n_xi=104))
dmodel = jb.build_model(dscene)
t0 = time.perf_counter()
study = design.make_study(dmodel, "lateral_max",
                          jb.RunOptions.from_scene(dscene).replace(solver=jb.make_solver("direct", "reuse")), t_eval=T_EVAL)
report = design.sensitivity_report(study, repeat=1)
print(f"N = {dmodel.n_unknowns}, {study.options.n_steps} steps; study + sensitivities in {time.perf_counter() - t0:.1f} s "
      f"(forward {report.forward_s:.2f} s, gradient {report.gradient_s:.2f} s, at the kink: {report.at_kink})")
for p in report.parameters:
    print(f"  {p.component:12s} {p.gradient:9.3f} µm/{p.unit}")
print("structurally zero:", ", ".join(z.component for z in report.structural_zero))
show_png("sensitivity.png", plot.plot_sensitivity, report)

# %% [markdown]
# In-plane translations (x, y) move the belt along its path but not sideways (slope 0). The
# lateral deviation is set by the translations along the roller axis — about one to one (≈ 1000
# µm/mm: the belt on the arc goes with the roller) — and by the tilts, 60–270 µm/mrad, the tilt
# about y (the skew) of roller 1 the strongest. A gradient away from the kink, checked against
# central differences on one component:

# %%
theta = jnp.zeros(study.space.size).at[study.space.index("roller 2", "ax")].set(0.2)
value, grad = design.value_and_gradient(study, theta)
k = study.space.index("roller 3", "ax")
h = 1e-3
e = jnp.zeros(study.space.size).at[k].set(h)
fd = (design.metric_value(study, theta + e) - design.metric_value(study, theta - e)) / (2 * h)
print(f"at roller 2 tilted 0.2 mrad: lateral_max {float(value):.3f} µm; d/d(roller 3:ax) "
      f"= {float(grad[k]):.5f} µm/mrad (reverse mode), {float(fd):.5f} (central difference)")

# %% [markdown]
# ## 3 · The tolerance box
#
# The largest box of per-component half-widths `h` such that every misalignment inside it keeps
# `lateral_max ≤ 20 µm`. The response is linear, so the worst corner follows from the Jacobian;
# `optax` maximises Σ log h under that worst case, then the box is **verified by full runs** at its
# worst and at random corners and rescaled until the verified worst case lies in [0.97, 1] × the
# limit. Components the metric does not feel are capped at 5 mm / 5 mrad.

# %%
t0 = time.perf_counter()
box = design.tolerance_box(study, LIMIT_UM)
print(f"box in {time.perf_counter() - t0:.1f} s: verified worst case {box.worst_case_um:.2f} µm "
      f"(linear prediction {box.predicted_worst_um:.2f} µm), {box.iterations} iteration(s)")
for lab, hw, u in zip(box.labels, box.half_widths, box.units):
    tag = "  (binding)" if lab in box.binding[:3] else "  (not felt: capped)" if lab in box.unconstrained else ""
    print(f"  {lab:12s} ± {hw:8.4g} {u}{tag}")
print(f"RSS stack-up with σ = h/3: {box.rss_um:.2f} µm (the worst case is the sum, RSS the statistical stack-up)")
show_png("box.png", plot.plot_tolerance_box, box)

# %% [markdown]
# The box is a few µm wide in z and a few hundredths of a mrad in the tilts: the belt on an arc
# follows an axial roller shift one to one, and 0.05 mrad of tilt already moves it by 3–13 µm.
# The in-plane translations are not felt (capped at 5 mm). The binding components — those whose
# share of the worst case the optimiser could not trade away — are the tilts of rollers 2 and 3.
# The same from the command line: `jaxbelt tolerance three-roller-tolerance --limit-um 20`.
#
# ## 4 · The yield
#
# Manufacturing scatters every component: take each normal with σ = h/2 (so the box is ±2σ per
# component — a deliberately loose process). Monte Carlo in `vmap` batches gives the yield with a
# Wilson interval; FORM (Hasofer–Lind–Rackwitz–Fiessler iterations with gradients through the whole
# run) and, near yield 1, importance sampling around FORM's design point.

# %%
dist = design.Distribution(tuple(box.labels), ("normal",) * len(box.labels), tuple(np.asarray(box.half_widths) / 2.0))
t0 = time.perf_counter()
# FORM and importance sampling run gradients through the whole run: left out of the quick run
sweep = design.run_sweep(study, dist, SAMPLES, LIMIT_UM, chunk=8 if SMALL else 50, with_form=not SMALL)
lo, hi = sweep.ci95
print(f"{SAMPLES} samples in {time.perf_counter() - t0:.1f} s: Monte-Carlo yield {sweep.yield_:.4f} "
      f"(95 %: {lo:.4f}–{hi:.4f})")
if sweep.form_yield is not None:
    print(f"FORM: yield {sweep.form_yield:.6f} (β = {sweep.form_beta:.2f}); linear RSS 3σ stack-up "
          f"{sweep.rss_3sigma_um:.1f} µm" + (f"; importance sampling {sweep.is_yield:.6f} (95 %: "
                                            f"{sweep.is_ci95[0]:.6f}–{sweep.is_ci95[1]:.6f})"
                                            if sweep.is_yield is not None else ""))
show_png("yield.png", plot.plot_yield, sweep.metric_values, LIMIT_UM, sweep)

# %% [markdown]
# Each component leaves the box with a probability of 4.6 % (±2σ), yet the yield is close to
# one: a failure needs several components near their worst signs at once, and the statistical
# stack-up (RSS, 3σ) stays below the limit. Monte Carlo with a few hundred samples sees no
# failure and can only bound the yield from below; FORM (one design point, the most probable
# failure mode) and importance sampling around it resolve the small failure probability, the
# latter within a narrow interval. With `jaxbelt sweep --rom auto` a validated reduced model
# stands in for the full runs away from the limit (README "Reduced models in the sweep").
#
# ## 5 · Belt walk on a skewed roller
#
# The source's 2D model does not transport the lateral displacement (its variant, kept by the
# design scenes): the lateral field is steady and every metric above settles. A real belt on a
# skewed roller *walks* — its material enters each roller normal to the axis and drifts sideways
# at a constant rate until it runs off. jaxbelt models it with `lateral_transport = true`
# (normal entry at the contact lines), checked against a loop of moving tensioned Timoshenko beams
# (`jaxbelt.lateral_theory`, docs/lateral.md). Roller 2 skewed by 0.5 mrad (rotation about y):

# %%
skew = np.zeros((3, 3))
skew[1, 1] = 0.5e-3  # roller 2 rotated about y by 0.5 mrad
walk = {}
for n_xi, dt in WALK_GRIDS:
    base = jb.load_scene("three-roller")
    wscene = base.replace(mesh=base.mesh.__class__(n_eta=WALK_ETA, n_xi=n_xi), time=base.time.__class__(dt=dt, t_end=WALK_T),
                          solver=base.solver.__class__(lateral_transport=True, linear_solver="reuse"))
    wmodel, wopts = jb.build_model(wscene), jb.RunOptions.from_scene(wscene)  # the scene's solver, Δt, steps
    t0 = time.perf_counter()
    _, wtr = jb.simulate(jb.with_misalignment(wmodel, rotation=jnp.asarray(skew)), **wopts)
    t = np.asarray(wtr.t)
    vbar = np.asarray(wtr.tracer_v).mean(axis=1)
    half = len(t) // 2
    rate = np.polyfit(t[half:], vbar[half:], 1)[0]  # the walk_rate metric's slope, over the second half
    ref = lateral_theory.scene_walk_rate(wscene, skew)
    walk[n_xi] = dict(t=t, vbar=vbar, rate=rate, margin=np.asarray(wtr.edge_margin))
    print(f"n_xi = {n_xi}, Δt = {dt} s ({wmodel.n_unknowns} unknowns, {len(t)} steps in {time.perf_counter() - t0:.1f} s): "
          f"walk rate {rate * 1e3:+.4f} mm/s, beam-loop reference {ref * 1e3:+.4f} mm/s ({100 * (rate / ref - 1):+.1f} %)")
w = walk[max(walk)]
loop = float(jnp.sum(wmodel.ell))  # m; the belt runs at 1 m/s
run_off = w["margin"][-1].min() / abs(w["rate"])
print(f"edge margin left after {w['t'][-1]:g} s: {w['margin'][-1].min() * 1e3:.1f} mm → at this rate the belt runs off "
      f"in about {run_off / 60:.0f} min ({run_off / loop:.0f} passes of the {loop:.2f} m loop)")

fig, axs = plt.subplots(1, 2, figsize=(12, 3.8), constrained_layout=True)
for n_xi, r in walk.items():
    axs[0].plot(r["t"], r["vbar"] * 1e3, label=f"n_ξ = {n_xi}: {r['rate'] * 1e3:+.4f} mm/s")
axs[0].plot(w["t"], ref * w["t"] * 1e3, "k--", lw=0.8, label=f"reference slope {ref * 1e3:+.4f} mm/s")
axs[0].set(xlabel="t [s]", ylabel="v̄ [mm]", title="belt walk, roller 2 skewed 0.5 mrad: mean lateral tracer displacement")
axs[0].legend(fontsize=8)
for j, name in enumerate(wmodel.roller_names):
    axs[1].plot(w["t"], w["margin"][:, j] * 1e3, label=name)
axs[1].set(xlabel="t [s]", ylabel="edge margin [mm]", title="distance from the belt edge to the roller end")
axs[1].legend(fontsize=8)
show(fig)

# %% [markdown]
# The walk rate agrees with the beam-loop reference on the design grid already: +1.2 % at
# n_ξ = 104 and +0.5 % at 208 in the full-size run ([lateral mechanics](../docs/lateral.md): within
# 0.52 % over K L = 0.3 … 98). For tolerances this is a second kind of limit: not a
# deviation but a *rate* — a skew tolerance follows from how long the belt may run before a
# tracking correction (the `walk_rate` metric of `jaxbelt.design`, with `lateral_transport =
# true`). The source's model, without lateral transport, cannot show this at all.
