"""Model order reduction on the 1D scenes.

1. POD-Galerkin (the source's form) modes vs error and single-configuration DMD on Table 6.1
   run 1: trained on the first 50 (POD) / 150 (DMD) pre-transport snapshots, compared with the
   full model over the next steps.
2. Held-out configuration (-6 mm drive translation; 9 rad/s for the models that take the speed):
   fully reduced POD, DMDc (POD-coordinate and Proctor forms), parametric DMD, and the source's
   multi-configuration DMD without inputs, trained on the nominal scene + Table 6.1 runs.
3. The residual error indicator against the true error of the fully reduced POD.

Errors are tracer RMSEs in µm. Writes ``results/rom_1d.json``."""

import jax.numpy as jnp

import jaxbelt as jb
from _common import load, write
from jaxbelt.rom import (belt_inputs, collect_first_order, collect_snapshots, first_order, fit_dmd, fit_dmdc,
                         fit_parametric_dmd, fit_pod, fit_reduced_pod, parameters, residual_indicator, rmse,
                         stack_controlled, tracer_operator)


def held_out(n_train=150, n_test=400):
    names = ["two-roller-1d", "two-roller-1d-train1", "two-roller-1d-train2"]
    loaded = [load(n) for n in names]
    ms = [m for m, _ in loaded]
    dt = loaded[0][1].dt  # the three scenes share their time step
    runs = [collect_first_order(m, jb.RunOptions(jb.make_solver(), n_train, dt)) for m in ms]
    m0 = ms[0]
    C = tracer_operator(m0)
    Cz = jnp.concatenate([C, jnp.zeros_like(C)], axis=1)
    same_speed = jb.with_misalignment(m0, translation=jnp.array([-6e-3, 0.0]))
    new_speed = same_speed.replace(omega=0.9 * m0.omega)
    truth = {k: jb.simulate(t, n_steps=n_test, dt=dt)[1].tracer_u for k, t in (("same", same_speed), ("new", new_speed))}
    res = {"train": names, "train_steps": n_train, "test_steps": n_test}

    def err(key, pred):  # tracer RMSE, µm
        return float(rmse(truth[key], pred)) * 1e6

    Z = jnp.concatenate([jnp.concatenate([r[1], r[2]], axis=1) for r in runs], axis=1)
    for r in (10, 20, 30):
        rom = fit_reduced_pod(m0, Z, dt, n_modes=r)
        out = rom.run(rom.project(new_speed, jb.initial_state(new_speed)), parameters(new_speed), n_test)
        res[f"reduced_pod_{r}_um"] = err("new", out.tracer_u)
        if r == 20:
            xi0 = rom.project(new_speed, jb.initial_state(new_speed))
            ind = residual_indicator(new_speed, rom.fields(jnp.concatenate([xi0[None], out.xi])), dt, stride=10)
            res["reduced_pod_20_indicator_um"] = float(ind.estimate_um[-1])
    # DMDc at the nominal speed: nominal + run 1 (same speed), tested on -6 mm
    post = [r[2] for r in runs[:2]]
    X, Y, U = stack_controlled(post, [belt_inputs(parameters(m), z.shape[1] - 1) for m, z in zip(ms[:2], post)])
    z0 = collect_first_order(same_speed, jb.RunOptions(jb.make_solver(), 1, dt))[2][:, 0]
    u = belt_inputs(parameters(same_speed), 1)[:, 0]
    for r in (10, 20, 30, 40):
        res[f"dmdc_pod_{r}_um"] = err("same", fit_dmdc(X, Y, U, rank=r).predict(z0, u, n_test, observe=Cz))
        res[f"dmdc_proctor_{r}_um"] = err(
            "same", fit_dmdc(X, Y, U, rank=r + 9, rank_out=r, method="proctor").predict(z0, u, n_test, observe=Cz))
    res["plain_dmd_multi_um"] = err("same", fit_dmd(X, Y, rank=30).predict(z0, n_test, observe=Cz))
    P = jnp.stack([parameters(m) for m in ms])
    for r in (10, 20, 30, 40):
        p = fit_parametric_dmd([r_[2] for r_ in runs], P, rank=r)
        res[f"pdmd_{r}_um"] = err("new", p.predict(parameters(new_speed), n_test + 1, observe=Cz)[1:])
    for k, v in res.items():
        print(k, v)
    return res


def main():
    m, opts = load("two-roller-1d-train1")
    dt = opts.dt
    state, X, _ = collect_snapshots(m, jb.RunOptions(jb.make_solver(), 50, dt))
    _, ref = jb.simulate(m, jb.make_solver("eliminated"), n_steps=100, dt=dt, y0=state)
    pod = {}
    for r in (1, 3, 5, 10, 20):
        _, tr = jb.simulate(m, fit_pod(m, X, n_modes=r), n_steps=100, dt=dt, y0=state)
        pod[r] = float(rmse(ref.tracer_u, tr.tracer_u)) * 1e6
        print(f"POD {r:3d} modes: RMSE {pod[r]:.4g} µm")
    state, X, Xd = collect_snapshots(m, jb.RunOptions(jb.make_solver(), 150, dt))
    Z = first_order(X, Xd)
    dmd = fit_dmd(Z).stable()
    _, tr = jb.simulate(m, n_steps=200, dt=dt, y0=state)
    C = tracer_operator(m)
    pred = dmd.predict(Z[:, -1], 200, observe=jnp.concatenate([C, jnp.zeros_like(C)], axis=1))
    dmd_err = float(rmse(tr.tracer_u_solved, pred)) * 1e6
    print(f"DMD rank {dmd.eigs.shape[0]}: RMSE over 200 steps {dmd_err:.4g} µm")
    held = held_out()
    write("rom_1d", {"held_out": held, "scene": "two-roller-1d-train1", "pod_train_steps": 50, "pod_test_steps": 100,
                     "pod_rmse_um_by_modes": pod, "dmd_train_steps": 150, "dmd_rank": int(dmd.eigs.shape[0]),
                     "dmd_rmse_um_200_steps": dmd_err})


if __name__ == "__main__":
    main()
