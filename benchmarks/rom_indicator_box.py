"""Why the error estimate erred high on DMDc over the 15-component box, and what fixed it.

The case of ``benchmarks/rom_indicator.py``: DMDc (rank 40) trained on the axial design over the
box (every translation of the three rollers +-3 mm, every tilt about x and y +-0.5 mrad; 31 runs
of 100 steps), predicting ``three-roller-t72`` and a configuration drawn in the box over 600
steps. Library calls; raw estimates (no safety factor) against the true tracer error of the full
model from the same start:

- *every residual through the exact Jacobian*: ``e_{k+1} = J e_k + δ_k`` with ``J`` at ``z_0``
  (600 sequential Jacobian-vector products: what the linearisation alone leaves);
- ``error_rom`` with its pieces switched on one after the other: windows of 10 steps (the first
  10 single), + the windows whose mean residual still changes cut into single steps,
  + the quasi-static response ``(I - J)⁻¹ r̄`` in the subspace (the default), and every step's
  residual through the subspace.

Reports the raw effectivity (estimate / true RMSE over the 600 steps), the ratio of the maxima
over time, the cost and the error at chosen steps (start-up transient, settled level).
Writes ``results/rom_indicator_box.json``.
Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/rom_indicator_box.py`` (about 10 minutes on 2 cores).
"""

import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import jaxbelt as jb
from _common import write
from jaxbelt import rom
from jaxbelt.design.sampling import distribution_from_dict
from jaxbelt.integrators import ReusedFactorisationBackwardEuler
from jaxbelt.rom.indicator import _apply_steps, _chunked, _step_map, error_rom
from rom_indicator import BOX, scenes

N, TRAIN, RANK = 600, 100, 40
SHOWN = [0, 1, 2, 5, 10, 15, 20, 30, 50, 100, 300, 599]


def rms_mm(E, Cz):
    return np.sqrt(np.mean((E @ Cz.T) ** 2, axis=1)) * 1e3


def main():
    import tomllib

    folder = Path(tempfile.mkdtemp())
    paths, _ = scenes(folder)
    t0 = time.perf_counter()
    nominal = jb.load_model("three-roller-t72")
    dist = distribution_from_dict(tomllib.loads(BOX), nominal)
    models, _, _ = rom.axial_design(nominal, dist.labels, rom.box_from_distribution(dist))
    params = [rom.parameters(m) for m in models]
    trajs = [rom.collect_first_order(m, TRAIN, ReusedFactorisationBackwardEuler.for_model(m))[2] for m in models]
    X, Y, U = rom.stack_controlled(trajs, [rom.belt_inputs(p, Z.shape[1] - 1) for p, Z in zip(params, trajs)])
    fit = rom.fit_dmdc(X, Y, U, rank=RANK)
    train_s = time.perf_counter() - t0
    print(f"trained on {len(models)} runs in {train_s:.0f} s", flush=True)
    out = dict(train_runs=len(models), train_steps=TRAIN, rank=RANK, predict_steps=N, shown_steps=SHOWN, cases={})
    for label, test in (("three-roller-t72", nominal), ("random in the box", jb.load_model(paths["three-roller-box-random1"]))):
        integ = ReusedFactorisationBackwardEuler.for_model(test)
        Zt = np.asarray(rom.collect_first_order(test, N, integ)[2])
        z0 = Zt[:, 0]
        u = rom.belt_inputs(rom.parameters(test), 1)[:, 0]
        basis = np.asarray(fit.basis)
        coords = np.asarray(jnp.concatenate([(fit.basis.T @ z0)[None], fit.predict(z0, u, N, observe=fit.basis.T)]))
        C = np.asarray(rom.tracer_operator(test))
        Cz = np.concatenate([C, np.zeros_like(C)], axis=1)
        Zr = coords @ basis.T
        true = rms_mm(Zt.T[1:] - Zr[1:], Cz)
        true_rmse = float(np.sqrt(np.mean(true**2)))
        row = dict(true_rmse_mm=true_rmse, true_max_mm=float(true.max()), true_mm_at=true[SHOWN].tolist(), variants={})

        # every residual through the exact Jacobian at z_0
        delta = _chunked(lambda Zb: _apply_steps(test, integ, "post", 1, Zb), Zr[:-1], 16, 0) - Zr[1:]
        F = _step_map(test, integ, "post", 1)
        jvp = jax.jit(lambda v: jax.jvp(F, (jnp.asarray(Zr[0]),), (v,))[1])
        e, lin = Zt[:, 0] - Zr[0], []
        for k in range(N):
            e = np.asarray(jvp(jnp.asarray(e))) + delta[k]
            lin.append(e)
        lin_mm = rms_mm(np.asarray(lin), Cz)
        row["variants"]["every residual, exact J"] = dict(
            raw_effectivity=float(np.sqrt(np.mean(lin_mm**2)) / true_rmse), max_ratio=float(lin_mm.max() / true.max()),
            estimate_mm_at=lin_mm[SHOWN].tolist(), full_step_equivalents=2 * N)
        variants = {"windows of 10": dict(refine_rtol=None, quasi_static=False),
                    "+ changing windows single": dict(quasi_static=False),
                    "+ quasi-static response (default)": dict(),
                    "every step's residual, subspace": dict(stride=1, dense=0, quasi_static=False),
                    "every step's residual, subspace + quasi-static": dict(stride=1, dense=0)}
        for name, kw in variants.items():
            r = error_rom(test, basis, coords, z_true0=z0, integrator=integ, **kw)
            est = np.asarray(r["error_mm"])
            row["variants"][name] = dict(raw_effectivity=r["rmse_mm"] / true_rmse, max_ratio=float(est.max() / true.max()),
                                         estimate_mm_at=est[SHOWN].tolist(), cost=r["cost"], dim=r["dim"],
                                         settled=r["settled"])
        print(label, f"true RMSE {true_rmse:.3e} mm")
        print("  true      ", " ".join(f"{v:.1e}" for v in true[SHOWN]))
        for name, v in row["variants"].items():
            print(f"  {name:48s} raw {v['raw_effectivity']:.2f}, max {v['max_ratio']:.2f}   ",
                  " ".join(f"{x:.1e}" for x in v["estimate_mm_at"]), flush=True)
        out["cases"][label] = row
    write("rom_indicator_box", out)


if __name__ == "__main__":
    main()
