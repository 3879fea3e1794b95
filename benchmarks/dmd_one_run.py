"""DMD on one configuration, as ``jaxbelt reduce SCENE --method dmd --train-steps 400`` runs it:
does it pay off against our fastest full run?

Scene ``three-roller-t72`` (5000 steps; the fastest full mode that reproduces the scene's own, as
``reduce`` picks it). In one process, for the exact DMD of 400 pre-transport snapshots with the
randomized SVD (``fit_dmd(svd="auto")``, the default) and with the full thin SVD: the offline
time (snapshot steps and fit), the online time (the prediction of the remaining 4600 steps), the
full run's time, the total speedup ``full / (offline + online)``, the RMSE of the tracers and,
for scale, the time of the 400 snapshot steps as a plain run. Best of three ``reduce`` calls per
variant (each call times its parts as the best of several). Then snapshots, fit and forecast as
one compiled program (``rom.dmd.dmd_forecast``, the randomized fit), best of five calls, against
the same full run. Run:
``OPENBLAS_NUM_THREADS=1 python benchmarks/dmd_one_run.py``. Writes ``results/dmd_one_run.json``.
"""

import dataclasses
import time
from unittest import mock

import jax
import jax.numpy as jnp
import numpy as np
from _common import write

import jaxbelt as jb
from jaxbelt import rom
from jaxbelt.bench.reduction import reduce_and_time
from jaxbelt.rom import dmd

SCENE, TRAIN = "three-roller-t72", 400


def main():
    jb.enable_x64()
    sc = jb.load_scene(SCENE)
    model, opts = jb.build_model(sc), jb.RunOptions.from_scene(sc)
    config = rom.ReduceConfig(method=rom.DMD(), options=opts.replace(saveat=jb.SaveAt()), train_steps=TRAIN, stride=0)
    fastest = jb.DirectBackwardEuler(jb.Reuse())
    jax.block_until_ready(jb.simulate(model, fastest, n_steps=TRAIN, dt=opts.dt))
    snap_s = min(_clock(lambda: jax.block_until_ready(jb.simulate(model, fastest, n_steps=TRAIN, dt=opts.dt)))
                 for _ in range(5))
    out = dict(scene=SCENE, train_steps=TRAIN, n_steps=opts.n_steps, snapshot_steps_s=snap_s, variants={})
    full_fit = dmd.fit_dmd
    for name, svd in (("randomized", "auto"), ("full", "full")):
        with mock.patch.object(rom.dmd, "fit_dmd", lambda X, rank=None, svd=svd: full_fit(X, rank=rank, svd=svd)):
            runs = [reduce_and_time(model, [model], config) for _ in range(3)]
        best = min(runs, key=lambda r: r.timings.offline_s + r.timings.online_s)
        t = dataclasses.asdict(best.timings)
        row = dict(offline_s=t["offline_s"], online_s=t["online_s"], full_run_s=t["full_run_s"],
                   full_mode=t["full_mode"], speedup_total=t["full_run_s"] / (t["offline_s"] + t["online_s"]),
                   offline_over_snapshot_steps=t["offline_s"] / snap_s, rmse_um=best.result.rmse_um, modes=best.result.modes)
        out["variants"][name] = row
        print(name, row, flush=True)
    # snapshots, fit and forecast as one compiled program (rom.dmd.dmd_forecast), the same fastest full run
    C = rom.tracer_operator(model)
    Cz = jnp.concatenate([C, jnp.zeros_like(C)], axis=1)
    n_pred = opts.n_steps - TRAIN

    def one():
        return jax.block_until_ready(dmd.dmd_forecast(model, jb.RunOptions(fastest, TRAIN, opts.dt), n_pred, Cz))

    fc = one()
    one_s = min(_clock(one) for _ in range(5))
    _, ref = jb.simulate(model, fastest, n_steps=opts.n_steps, dt=opts.dt)
    steps = np.rint(np.asarray(ref.t) / opts.dt).astype(int)
    rows = steps > TRAIN
    truth = np.asarray(ref.tracer_u_solved)[rows]
    pred = np.asarray(fc.observed)[steps[rows] - TRAIN - 1]
    full_s = out["variants"]["randomized"]["full_run_s"]
    out["variants"]["one_program"] = dict(
        total_s=one_s, full_run_s=full_s, speedup_total=full_s / one_s, total_over_snapshot_steps=one_s / snap_s,
        rmse_um=float(rom.rmse(truth, pred)) * 1e6, modes=int(fc.rank), sketch_full=bool(fc.sketch_full))
    print("one program", out["variants"]["one_program"], flush=True)
    write("dmd_one_run", out)


def _clock(f):
    t0 = time.perf_counter()
    f()
    return time.perf_counter() - t0


if __name__ == "__main__":
    main()
