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
# # 7 · Belt steering: the loop, its plant, its gains, and the 20 µm question on a steered belt
#
# With lateral transport on, every skewed or twisted roller walks the belt at a steady rate
# (notebook 6, section 5), so no roller tolerance alone keeps a running belt within 20 µm. A
# real precision belt is held by a *steering roller*: an edge sensor feeds a controller that
# tilts one roller. The source notes that such systems rely on registering the belt's position,
# not on a model that predicts it; jaxbelt has that model, differentiable, and here it designs
# the loop and asks the design question of the steered machine.
#
# 1. open loop against closed loop: the belt edge at the sensor and the actuator angle;
# 2. the plant, identified from the model with the loop open, and its Bode plot;
# 3. PI gains fitted by `optax` through the whole closed-loop run, within gain and phase margins;
# 4. the tolerance box of the steered machine beside the source's variant.
#
# `JAXBELT_NOTEBOOK_SMALL=1` (the test suite) runs coarse grids and short runs.

# %%
import os

import jax
import jax.numpy as jnp
import matplotlib.pyplot as plt
import numpy as np

import jaxbelt as jb
from jaxbelt import design, plot
from jaxbelt.steering.report import steering_report
from jaxbelt.steering.tuning import tune

jb.enable_x64()  # jaxbelt's results are meant in float64
SMALL = os.environ.get("JAXBELT_NOTEBOOK_SMALL") == "1"  # the test suite's quick run
STEERED = "two-roller-steered" if SMALL else "three-roller-steered"  # sections 1, 2 and 4
T_LOOP = 6.0 if SMALL else 20.0  # s: section 1's runs
TUNE_T, TUNE_ITER = (8.0, 3) if SMALL else (40.0, 40)  # section 3: run length, Adam iterations
COARSE = SMALL  # section 4 on a coarse copy of the design scenes
LIMIT_UM = 20.0


def coarse(scene):
    """A coarse copy of a three-roller design scene (3 grid lines across, 5 elements per arc)."""
    return scene.replace(mesh=scene.mesh.__class__(n_eta=3, roller_elements=(5, 5, 5), free_elements=(10, 7, 7)),
                         time=scene.time.__class__(scene.time.dt, 2.0))


# %% [markdown]
# ## 1 · Open loop against closed loop
#
# The scene's `[[control]]` table puts an edge sensor past the steering roller and a PI
# controller on the roller's tilt (`jaxbelt.control`: sampled, with a range, a rate limit and a
# lag). Its gains are magnitudes; the loop's sign comes from the machine's steering coefficient.
# The loop is part of the model and its state rides in the scan's carry, so open and closed
# loop are one `vmap` over the gains. A roller misalignment disturbs both runs alike.

# %%
scene = jb.load_scene(STEERED)
model = jb.build_model(scene)
opts = jb.RunOptions.from_scene(scene)
n_loop = int(round(T_LOOP / opts.dt))
rot = np.zeros((model.n_rollers, 3))
rot[0, 0] = 0.3e-3  # roller 1 tilted 0.3 mrad about x on top of the scene's own misalignment
base_rot = np.asarray(model.chi_static).reshape(model.n_rollers, -1)[:, 3:6]
tilted = jb.with_misalignment(model, rotation=jnp.asarray(base_rot + rot))
gains = jnp.stack([jnp.zeros(2), jnp.array([float(model.control.kp[0]), float(model.control.ki[0])])])


def run(g):
    m = tilted.replace(control=tilted.control.with_gains(g[0], g[1]))
    _, tr = jb.simulate(m, opts.solver, n_steps=n_loop, dt=opts.dt, check=False)
    return tr.t, tr.sensor_v[:, 0], tr.control_u[:, 0]


t, sensor, angle = jax.jit(jax.vmap(run))(gains)
fig, axes = plt.subplots(1, 2, figsize=(12, 3.8), constrained_layout=True)
for i, label in enumerate(["open loop", "closed loop (the scene's PI gains)"]):
    axes[0].plot(t[i], sensor[i] * 1e6, label=label)
    axes[1].plot(t[i], angle[i] * 1e3, label=label)
axes[0].set(xlabel="t [s]", ylabel="belt at the sensor v [µm]", title=f"{STEERED}: roller 1 tilted 0.3 mrad")
axes[1].set(xlabel="t [s]", ylabel="actuator angle [mrad]")
for ax in axes:
    ax.grid(alpha=0.3)
    ax.legend()
plt.show()
print(f"open loop: {float(sensor[0, -1]) * 1e6:.1f} µm at the sensor after {T_LOOP:g} s and walking; "
      f"closed loop: {float(sensor[1, -1]) * 1e6:.2f} µm, actuator at {float(angle[1, -1]) * 1e3:.4f} mrad")

# %% [markdown]
# ## 2 · The plant, from the model
#
# `steering_report` (the library behind `jaxbelt steering`) runs the machine with the loop open:
# with and without a step of the actuator angle, and aligned. The steady walk per mrad of angle
# is the *steering coefficient* that makers measure on their machines; the walk the scene's own
# misalignments cause, divided by it, is the angle the loop must hold. The step response is fitted
# by a low-order transfer function with a once-around recirculation (the belt's lateral
# position comes round the loop on the rollers), whose Bode plot is below.

# %%
report = steering_report(model, opts, sensitivity=False)
plant = report.plant
print(f"coefficient {report.coefficient_mm_s_per_mrad:.4g} mm/s per mrad; disturbance {report.disturbance_mm_s:.4g} mm/s; "
      f"hold angle {report.hold_angle_mrad:.4g} mrad (range ±{report.limit_mrad:g}); plant fit within "
      f"{100 * report.plant_fit_error:.1f} % of the response's range; P-loop boundary k_p = "
      f"{report.plant_gain_margin:.3g} mrad/mm")
omega = np.logspace(-2, 1.5, 600)
G = plant.frequency_response(omega) * 1e-3  # m/s per rad → mm per mrad (× 1/s)
fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 6), sharex=True, constrained_layout=True)
a1.loglog(omega, np.abs(G))
a1.set(ylabel="|G(iω)| [mm per mrad]", title=f"identified steering plant of {STEERED}")
a2.semilogx(omega, np.degrees(np.unwrap(np.angle(G))))
a2.axhline(-180, color="0.5", lw=0.8, ls="--")
a2.set(xlabel="ω [rad/s]", ylabel="phase [deg]")
for ax in (a1, a2):
    ax.grid(alpha=0.3, which="both")
plt.show()

# %% [markdown]
# ## 3 · Gains fitted through the closed loop
#
# `tune` (the library behind `jaxbelt tune`) minimises the integrated squared sensor error
# after the scene's disturbance and edge profile, with gradients through the whole closed-loop
# run (`optax`'s Adam on log-gains), keeping the gain margin ≥ 6 dB and the phase margin ≥ 45°.
# Beside it the classical rules (SIMC, Ziegler–Nichols) for the same plant, each run through the
# full model. It runs on the small two-roller machine, where a run takes a fraction of a second.

# %%
tscene = jb.load_scene("two-roller-steered")
tmodel = jb.build_model(tscene)
topts = jb.RunOptions.from_scene(tscene).replace(n_steps=int(round(TUNE_T / tscene.time.dt)))
res = tune(tmodel, topts, kind="ise", iterations=TUNE_ITER)
fig, ax = plt.subplots(figsize=(7, 3.5), constrained_layout=True)
ax.semilogy(np.arange(len(res.history)), res.history, "o-", ms=3)
ax.set(xlabel="Adam iteration", ylabel="ISE [µm² s]", title="tuning progress (two-roller-steered)")
ax.grid(alpha=0.3, which="both")
plt.show()
print(f"{'gains':16s} {'kp':>6s} {'ki':>6s} {'ISE µm² s':>11s} {'GM dB':>7s} {'PM °':>6s}  within the margins")
for p in (res.start, res.tuned, *res.classical):
    print(f"{p.rule:16s} {p.kp_mrad_per_mm:6.3g} {p.ki_mrad_per_mm_s:6.3g} {p.ise_um2_s:11.4g} "
          f"{p.response_gain_margin_db:7.3g} {p.response_phase_margin_deg:6.3g}  {'yes' if p.feasible else 'no'}")

# %% [markdown]
# ## 4 · The 20 µm question, steered and not
#
# On the steered machine the metrics are read over a window of steady operation with the loop
# closed, against the aligned machine with its loop closed: lateral and longitudinal deviation
# within 20 µm and the actuator within its range, all at once. The source's variant has no walk,
# no tension and no loop, and is read at one instant. Both boxes are verified by full runs.

# %%
answers = {}
for name in ("three-roller-steered", "three-roller-tolerance"):
    sc = jb.load_scene(name)
    sc = coarse(sc) if COARSE else sc
    m, o = jb.build_model(sc), jb.RunOptions.from_scene(sc)
    study = design.make_study(m, "lateral_max", o)
    limits = {"longitudinal_max": LIMIT_UM, "steering_max": study.range_mrad} if study.steered else None
    answers[name] = design.tolerance_box(study, LIMIT_UM, limits=limits)
labels = answers["three-roller-steered"].labels
fig, ax = plt.subplots(figsize=(11, 4), constrained_layout=True)
x = np.arange(len(labels))
for k, (name, box) in enumerate(answers.items()):
    hw = np.where(np.isin(box.labels, box.unconstrained), np.nan, np.asarray(box.half_widths))
    ax.bar(x + (k - 0.5) * 0.4, hw * 1e3, 0.4, label=name)
ax.set_yscale("log")
ax.set_xticks(x, labels, rotation=60, fontsize=8)
ax.set(ylabel="half-width [µm or µrad]", title="largest verified tolerance box (missing bar: not felt)")
ax.grid(alpha=0.3, axis="y")
ax.legend()
plt.show()
for name, box in answers.items():
    print(f"{name}: verified worst case {box.worst_case_um:.4g} (limit {LIMIT_UM:g}), binding: {box.binding_limit or box.metric}")
