"""Parametric DMD in 2D, on the box of ``rom_box_2d.py``.

Same box, training and tests as ``rom_box_2d.py``: every free component of the three rollers of
``three-roller`` (15), ±3 mm / ±0.5 mrad; the axial design (aligned + each component at ±h, 31
runs, reuse solver), ``TRAIN`` steps of each, every ``STRIDE``-th post-transport state; tests
``three-roller-t72`` and ``N_RANDOM`` configurations uniform in the box (all 15 components at
once, the same seed), ``STEPS`` steps, tracer RMSE (longitudinal ``u``, lateral ``v``) against the
full model.

Parametric DMD (:func:`jaxbelt.rom.fit_parametric_dmd`, partitioned: one POD basis of all
training snapshots, one DMD per training configuration in it, forecasts combined with the
minimum-norm affine weights ``w`` of :func:`jaxbelt.rom.interpolation_weights`), with the
training trajectories starting at

* ``z0``: the configuration's initial state (the static equilibrium), snapshots
  ``z_0, z_4, … z_400``;
* ``z4``: the state after the first ``STRIDE`` steps, snapshots ``z_4, … z_400`` (the prediction's
  ``k = 0`` is then step 4, and it never needs the test configuration's state);

at common ranks ``RANKS``, per-configuration DMD ranks ``DMD_RANKS`` (``None``: every
non-negligible singular value) and, at rank 40, the stability cuts ``CUTS`` (``|λ| > 1 + tol``
dropped; ``None``: keep every mode). Beside each prediction the script measures what it is made
of:

* ``interp_exact``: the same weights applied to the *full-model* trajectories of the training
  configurations (run for the whole test horizon) — the error of the interpolation alone, what
  parametric DMD would give with perfect per-configuration forecasts;
* ``forecast_own_config``: each per-configuration DMD's forecast of its *own* configuration over
  the test horizon (``STEPS`` steps from ``TRAIN`` steps of training), against that
  configuration's full run;
* ``sum_abs_w_forecast``: ``Σ |w_j| forecast_j`` — the prediction minus ``interp_exact`` is
  ``Σ w_j (forecast_j − full_j)``, so this bounds the part of the error the weights amplify
  (triangle inequality).

DMD with control on the same snapshots (rank 40, as ``rom_box_2d.py``) runs beside it as the
replacement. Writes ``results/pdmd_2d.json``. Run: ``OPENBLAS_NUM_THREADS=1 python
benchmarks/pdmd_2d.py [--quick]`` (~8 min on 2 loaded cores).
"""

import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

import jaxbelt as jb
from _common import load, write
from jaxbelt.misalignment import apply, parameter_space
from jaxbelt.rom import (axial_design, belt_inputs, collect_first_order, fit_dmdc, fit_parametric_dmd,
                         interpolation_weights, parameters, position_in_box, rmse, stack_controlled, state_to_z,
                         tracer_operator)

QUICK = "--quick" in sys.argv
TRAIN, STRIDE, STEPS, N_RANDOM = (100, 4, 300, 1) if QUICK else (400, 4, 1500, 4)
RANKS = (20, 40, 80, 160)
DMD_RANKS = (None, 40)
CUTS = (1e-5, 1e-8, None)  # the default (first), a tighter cut, no cut
STARTS = {"z0": 0, "z4": STRIDE}  # index of the first snapshot kept (post-transport states z_0 … z_STEPS)
REUSE = jb.DirectBackwardEuler(jb.Reuse())


def um(x):
    return float(x) * 1e6


def errors(ref, pred, ntr):
    """Tracer RMSE (µm) of ``pred`` (n, 2 n_tr) against ``ref`` (n, 2 n_tr): longitudinal, lateral."""
    return {"rmse_u_um": um(rmse(ref[:, :ntr], pred[:, :ntr])), "rmse_v_um": um(rmse(ref[:, ntr:], pred[:, ntr:]))}


def label(key):
    st, r, dr, cut = key
    return f"pDMD from {st} r={r} dmd_rank={dr} cut={cut}"


def main():
    nominal, opts = load("three-roller")
    dt = opts.dt
    space = parameter_space(nominal)
    h = np.array([3.0 if c.startswith("d") else 0.5 for _, c in space.entries])
    models, thetas, space = axial_design(nominal, space.labels(), h)
    C, Cz = tracer_operator(nominal), tracer_operator(nominal, "z")
    ntr = C.shape[0]
    obs = jnp.concatenate([jnp.concatenate([C, jnp.zeros_like(C)], 1), jnp.concatenate([Cz, jnp.zeros_like(C)], 1)])
    sel = slice(STRIDE - 1, STEPS, STRIDE)  # the full run's steps STRIDE, 2 STRIDE, … STEPS

    # training runs for the whole test horizon: the first TRAIN steps give the snapshots, all of it
    # the full-model trajectory of each training configuration (interp_exact, forecast_own_config)
    t0 = time.perf_counter()
    trajs, full_train, mus = [], [], []
    for m in models:
        _, _, Zq = collect_first_order(m, jb.RunOptions(REUSE, STEPS, dt))
        trajs.append(Zq[:, :TRAIN + 1:STRIDE])  # z_0, z_STRIDE, … z_TRAIN (the start state first)
        full_train.append(np.asarray((obs @ Zq[:, 1:]).T)[sel])  # steps STRIDE … STEPS: (STEPS / STRIDE, 2 n_tr)
        mus.append(parameters(m))
        del Zq
    full_train = np.stack(full_train)
    t_runs = time.perf_counter() - t0
    print(f"{len(models)} training runs of {STEPS} steps: {t_runs:.1f} s", flush=True)

    variants = [(st, r, dr, CUTS[0]) for st in STARTS for r in RANKS for dr in DMD_RANKS]
    variants += [(st, 40, dr, cut) for st in STARTS for dr in DMD_RANKS for cut in CUTS[1:]]
    models_pd, fit_s, svd_s, sing = {}, {}, {}, {}
    for st, k0 in STARTS.items():
        t0 = time.perf_counter()
        tr_st = [t[:, k0 // STRIDE:] for t in trajs]
        U, s, _ = jnp.linalg.svd(jnp.concatenate(tr_st, axis=1), full_matrices=False)
        U = U[:, :max(RANKS)]
        svd_s[st], sing[st] = time.perf_counter() - t0, (np.asarray(s[:max(RANKS) + 1]) / float(s[0])).tolist()
        # forecasts of the steps STRIDE … STEPS: k = 0 is z_{k0}; from z_0, k = 0 (the start) is dropped
        skip = 1 if k0 == 0 else 0
        n_pred = STEPS // STRIDE + skip
        for key in (v for v in variants if v[0] == st):
            _, r, dr, cut = key
            t0 = time.perf_counter()
            pd = fit_parametric_dmd(tr_st, thetas, rank=r, dmd_rank=dr, basis=U, discard_unstable=cut is not None,
                                    unstable_tol=1e-5 if cut is None else cut)
            coef = pd.coefficients(n_pred)[:, skip:]  # (J, STEPS / STRIDE, r)
            jax.block_until_ready(coef)
            fit_s[key] = time.perf_counter() - t0
            models_pd[key] = (pd, np.asarray(coef @ (obs @ pd.basis).T), skip, n_pred)  # per-config tracer forecasts
    print(f"common SVDs {svd_s}; pDMD fits {sum(fit_s.values()):.1f} s", flush=True)

    t0 = time.perf_counter()
    post = [t for t in trajs]
    X, Y, Uin = stack_controlled(post, [belt_inputs(mu, z.shape[1] - 1) for mu, z in zip(mus, post)])
    dmdc = fit_dmdc(X, Y, Uin, rank=40)
    t_dmdc = time.perf_counter() - t0

    # per-configuration forecasts of their own configuration (the errors the weights multiply)
    forecast = {}
    for key, (pd, tr, _, _) in models_pd.items():
        e = [errors(full_train[j], tr[j], ntr) for j in range(len(models))]
        forecast[key] = {"rmse_u_um": [x["rmse_u_um"] for x in e], "rmse_v_um": [x["rmse_v_um"] for x in e],
                         "n_modes_kept": np.sum(np.abs(np.asarray(pd.amplitudes)) > 0, axis=1).tolist(),
                         "max_abs_eig": np.max(np.abs(np.asarray(pd.eigs)), axis=1).tolist()}

    rng = np.random.default_rng(1)  # the tests of rom_box_2d.py
    t72 = load("three-roller-t72")[0]
    pos, outside = position_in_box(t72, space, h)
    assert not outside, outside
    tests = {"three-roller-t72": (t72, pos * h)}
    for i in range(N_RANDOM):
        th = rng.uniform(-h, h)
        tests[f"random {i + 1} (all 15 components)"] = (apply(models[0], space, th, base=models[0].chi_static), th)
    rows = {}
    for name, (mt, th) in tests.items():
        _, ref = jb.simulate(mt, REUSE, n_steps=STEPS, dt=dt)
        full = np.concatenate([np.asarray(ref.tracer_u), np.asarray(ref.tracer_v)], axis=1)[sel]
        w = np.asarray(interpolation_weights(thetas, th))
        row = {"theta_in_box_units_max": float(np.max(np.abs(th / h))),
               "weights": {"sum_abs": float(np.sum(np.abs(w))), "max_abs": float(np.max(np.abs(w))),
                           "min": float(np.min(w)), "nominal": float(w[0]),
                           "reproduces_theta": float(np.max(np.abs(w @ thetas - th)))},
               "max_tracer_v_um": um(np.max(np.abs(full[:, ntr:]))),
               "interp_exact": errors(full, np.einsum("j,jnk->nk", w, full_train), ntr)}
        for key, (pd, tr, skip, n_pred) in models_pd.items():
            pred = np.asarray(pd.predict(th, n_pred, observe=obs))[skip:]
            amp = {d: float(np.sum(np.abs(w) * np.asarray(forecast[key][f"rmse_{d}_um"]))) for d in "uv"}
            row[label(key)] = {**errors(full, pred, ntr),
                               "sum_abs_w_forecast_u_um": amp["u"], "sum_abs_w_forecast_v_um": amp["v"]}
        pred = dmdc.predict(state_to_z(mt, jb.initial_state(mt), dt), belt_inputs(parameters(mt), 1)[:, 0],
                            STEPS // STRIDE, observe=obs)
        row["DMDc r=40 (every 4th step)"] = errors(full, np.asarray(pred), ntr)
        rows[name] = row
        best = min((k for k in row if k.startswith("pDMD")), key=lambda k: row[k]["rmse_u_um"] + row[k]["rmse_v_um"])
        print(name, "weights", {k: round(v, 3) for k, v in row["weights"].items()}, "interp_exact",
              {k: round(v, 3) for k, v in row["interp_exact"].items()}, "best pDMD", best,
              {k: round(v, 2) for k, v in row[best].items()}, "DMDc",
              {k: round(v, 3) for k, v in row["DMDc r=40 (every 4th step)"].items()}, flush=True)

    summary = {}
    for key in models_pd:
        summary[label(key)] = {
            "held_out_rmse_u_um": [rows[n][label(key)]["rmse_u_um"] for n in rows],
            "held_out_rmse_v_um": [rows[n][label(key)]["rmse_v_um"] for n in rows],
            "forecast_own_config_rmse_u_um_median_max": [float(np.median(forecast[key]["rmse_u_um"])),
                                                         float(np.max(forecast[key]["rmse_u_um"]))],
            "forecast_own_config_rmse_v_um_median_max": [float(np.median(forecast[key]["rmse_v_um"])),
                                                         float(np.max(forecast[key]["rmse_v_um"]))],
            "fit_s": fit_s[key]}
    summary["interp_exact"] = {"rmse_u_um": [rows[n]["interp_exact"]["rmse_u_um"] for n in rows],
                               "rmse_v_um": [rows[n]["interp_exact"]["rmse_v_um"] for n in rows]}
    summary["DMDc r=40"] = {"rmse_u_um": [rows[n]["DMDc r=40 (every 4th step)"]["rmse_u_um"] for n in rows],
                            "rmse_v_um": [rows[n]["DMDc r=40 (every 4th step)"]["rmse_v_um"] for n in rows]}
    for k, v in summary.items():
        print(k, {a: np.round(b, 3).tolist() if isinstance(b, list) else round(b, 2) for a, b in v.items()})
    write("pdmd_2d" + ("_quick" if QUICK else ""),
          {"box_half_widths": dict(zip(space.labels(), h.tolist())), "training_runs": len(models), "train_steps": TRAIN,
           "stride": STRIDE, "test_steps": STEPS, "ranks": list(RANKS), "dmd_ranks": [str(r) for r in DMD_RANKS],
           "cuts": [str(c) for c in CUTS], "starts": STARTS, "singular_values_rel": sing,
           "training_runs_s": t_runs, "svd_s": svd_s, "dmdc_fit_s": t_dmdc, "summary": summary,
           "forecast_own_config": {label(k): v for k, v in forecast.items()}, "rows": rows})


if __name__ == "__main__":
    main()
