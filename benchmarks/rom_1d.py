"""POD-Galerkin modes vs error and single-configuration DMD on the 1D Table 6.1 run 1.

Trains on the first 50 (POD) / 150 (DMD) pre-transport snapshots and compares the next steps'
tracers with the full model. Writes ``results/rom_1d.json``."""

import jax.numpy as jnp

import jaxbelt as jb
from jaxbelt.rom import collect_snapshots, first_order, fit_dmd, fit_pod, rmse, tracer_operator
from _common import write


def main():
    m = jb.load_model("two-roller-1d-train1")
    state, X, _ = collect_snapshots(m, 50)
    _, ref = jb.simulate(m, "eliminated", state=state, n_steps=100)
    pod = {}
    for r in (1, 3, 5, 10, 20):
        _, tr = jb.simulate(m, fit_pod(m, X, n_modes=r), state=state, n_steps=100)
        pod[r] = float(rmse(ref.tracer_u, tr.tracer_u)) * 1e3
        print(f"POD {r:3d} modes: RMSE {pod[r]:.3e} mm")
    state, X, Xd = collect_snapshots(m, 150)
    Z = first_order(X, Xd)
    dmd = fit_dmd(Z).stable()
    _, tr = jb.simulate(m, state=state, n_steps=200)
    C = tracer_operator(m)
    pred = dmd.predict(Z[:, -1], 200, observe=jnp.concatenate([C, jnp.zeros_like(C)], axis=1))
    dmd_err = float(rmse(tr.tracer_u_solved, pred)) * 1e3
    print(f"DMD rank {dmd.eigs.shape[0]}: RMSE over 200 steps {dmd_err:.3e} mm")
    write("rom_1d", {"scene": "two-roller-1d-train1", "pod_train_steps": 50, "pod_test_steps": 100,
                     "pod_rmse_mm_by_modes": pod, "dmd_train_steps": 150, "dmd_rank": int(dmd.eigs.shape[0]),
                     "dmd_rmse_mm_200_steps": dmd_err})


if __name__ == "__main__":
    main()
