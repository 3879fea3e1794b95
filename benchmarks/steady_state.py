"""Steady operation solved directly against time-stepping to the same settledness.

On the design scene (the steered three-roller machine), aligned and with misalignments of the size
the tolerance box allows, noise and edge profile off (:func:`jaxbelt.steady.quiet`): the steady
solve (:func:`jaxbelt.steady.steady_state`: compile time, best warm time of ``--repeat``, Newton
steps, GMRES iterations, residual; and the same solve without its mass-transport preconditioner)
beside a time-stepped run of the same machine from its static equilibrium, the
time it needs until its lateral deviation from the aligned machine stays within 0.5 % of a 20 µm
limit of the steady one, and the wall time of those steps. Also the steady deviation against the
run's at its end. ``tangents``: the aligned machine's tracer derivatives with respect to all 18
roller translations and rotations (forward mode, relative residual 1e-6 as a design study asks),
best warm time with and without the preconditioner, at the known steady state and through the
solve. ``solve_with_tangents``: the solve and those tangents in one program (what a design study
runs), first call (compilation) and warm, against the solve's and the tangents' own programs.

Run: ``python benchmarks/steady_state.py [--t-end 80] [--repeat 3]``. Writes
``results/steady_state.json``.
"""

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

import jaxbelt as jb
from _common import load, timed, write
from jaxbelt.misalignment import aligned, with_misalignment
from jaxbelt.steady import forward_jacobian, period_steps, quiet, steady_state, steady_tangents, steady_with_tangents
from jaxbelt.timeloop import compile_simulation, tracer_values

LIMIT_UM = 20.0
SETTLED = 0.005 * LIMIT_UM  # µm
CASES = {  # roller translations (m) and rotations (rad) per roller
    "aligned": (None, None),
    "roller 1 dy 18.4 um": ([[0, 18.4e-6, 0], [0, 0, 0], [0, 0, 0]], None),
    "roller 1 about x 3.45 urad": (None, [[3.45e-6, 0, 0], [0, 0, 0], [0, 0, 0]]),
    "roller 2 about y 0.139 mrad": (None, [[0, 0, 0], [0, 0.139e-3, 0], [0, 0, 0]]),
}


def timed_solve(model, solver, dt, repeat, precondition=True):
    t0 = time.perf_counter()
    s = jax.block_until_ready(steady_state(model, solver, dt=dt, precondition=precondition))
    first = time.perf_counter() - t0
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        s = jax.block_until_ready(steady_state(model, solver, dt=dt, precondition=precondition))
        times.append(time.perf_counter() - t0)
    return s, first, min(times)


def tangents(model, solver, dt, repeat, precondition):
    """The aligned machine's tracer derivatives with respect to every roller translation and
    rotation (the design study's tangents, relative residual 1e-6): best warm seconds of the
    tangent solves at the known steady state (:func:`jaxbelt.steady.steady_tangents`), and of ``jacfwd``-style differentiation through the solve
    (:func:`jaxbelt.steady.forward_jacobian`: the nonlinear solve again, then the same tangents)."""
    n_p = period_steps(model, dt)
    configure = lambda theta: with_misalignment(  # noqa: E731
        model, translation=theta[:9].reshape(3, 3), rotation=theta[9:].reshape(3, 3))
    theta = jnp.zeros(18)
    s = steady_state(model, solver, dt=dt, period_steps=n_p, precondition=precondition)
    at = jax.jit(lambda s: steady_tangents(configure, theta, s, solver, dt=dt, tangent_rtol=1e-6,
                                           precondition=precondition, outputs=lambda m, st, r: tracer_values(m, st.u)[1]))
    _, best_at, J = timed(at, s, repeat=repeat)

    def tracers(theta):
        s = steady_state(configure(theta), solver, dt=dt, period_steps=n_p, tangent_rtol=1e-6, precondition=precondition)
        return s.tracer_v

    fn = jax.jit(lambda th: forward_jacobian(tracers, th))
    _, best_through, J_through = timed(fn, theta, repeat=repeat)
    return best_at, best_through, np.asarray(J), float(np.abs(np.asarray(J) - np.asarray(J_through)).max() / np.abs(J).max())


def one_program(model, solver, dt, repeat):
    """The steady solve and the 18 tangents in one program (:func:`jaxbelt.steady.steady_with_tangents`,
    what a design study runs) against the solve's program and the tangents' program at the known
    solution: first-call seconds (tracing, compilation and one run) and best warm seconds of each,
    and the one program's largest difference from the separate tangents, relative."""
    n_p = period_steps(model, dt)
    q = model.chi_static.size
    configure = lambda theta: model.replace(chi_static=model.chi_static + theta)  # noqa: E731
    tracers = lambda m, st, r: tracer_values(m, st.u)[1]  # noqa: E731
    both = jax.jit(lambda m: steady_with_tangents(m, solver, dt=dt, directions=jnp.eye(q), period_steps=n_p,
                                                  tangent_rtol=1e-6))
    solve = jax.jit(lambda m: steady_state(m, solver, dt=dt, period_steps=n_p))
    at = jax.jit(lambda s: steady_tangents(configure, jnp.zeros(q), s, solver, dt=dt, tangent_rtol=1e-6, outputs=tracers))
    first_both, best_both, (s, J) = timed(both, model, repeat=repeat)
    first_solve, best_solve, s_alone = timed(solve, model, repeat=repeat)
    first_at, best_at, J_at = timed(at, s_alone, repeat=repeat)
    J_at = np.asarray(J_at)
    return dict(parameters=q, one_program_first_s=first_both, one_program_s=best_both,
                solve_first_s=first_solve, tangents_first_s=first_at, solve_s=best_solve, tangents_s=best_at,
                relative_difference=float(np.abs(np.asarray(J[1]) - J_at).max() / np.abs(J_at).max()))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="three-roller-steered")
    ap.add_argument("--t-end", type=float, default=80.0)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    model, opts = load(args.scene)
    model = quiet(aligned(model))
    dt, solver = opts.dt, opts.solver
    n = int(round(args.t_end / dt))
    every = 5
    run = compile_simulation(model, solver, n_steps=n, dt=dt, saveat=jb.SaveAt(every=every))
    ref_s, first, warm = timed_solve(model, solver, dt, args.repeat)
    _, ref_tr = jax.block_until_ready(run(model, dt))
    t0 = time.perf_counter()
    jax.block_until_ready(run(model, dt))
    run_s = time.perf_counter() - t0
    rows = []
    for name, (tr_, rot) in CASES.items():
        m = model if tr_ is None and rot is None else with_misalignment(
            model, translation=None if tr_ is None else jnp.asarray(tr_), rotation=None if rot is None else jnp.asarray(rot))
        s, first_s, warm_s = timed_solve(m, solver, dt, args.repeat)
        s_plain, _, warm_plain_s = timed_solve(m, solver, dt, args.repeat, precondition=False)
        _, tr = jax.block_until_ready(run(m, dt))
        dev_run = (np.asarray(tr.tracer_v) - np.asarray(ref_tr.tracer_v)) * 1e6  # (k, n_tr) µm
        dev_steady = (np.asarray(s.tracer_v) - np.asarray(ref_s.tracer_v)) * 1e6
        du_run = (np.asarray(tr.tracer_u[-1]) - np.asarray(ref_tr.tracer_u[-1])) * 1e6
        du_steady = (np.asarray(s.tracer_u) - np.asarray(ref_s.tracer_u)) * 1e6
        gap = np.abs(dev_run - dev_steady[None]).max(axis=1)
        outside = np.flatnonzero(gap > SETTLED)
        k_settled = 0 if outside.size == 0 else int(outside[-1]) + 1
        settled = k_settled < len(gap)
        t_settle = float(np.asarray(tr.t)[k_settled]) if settled else None
        rows.append(dict(
            case=name, newton_steps=int(s.newton_steps), krylov_iterations=int(s.krylov_iterations),
            residual_um=float(s.residual), converged=bool(s.converged),
            solve_first_s=first_s, solve_warm_s=warm_s,
            unpreconditioned=dict(newton_steps=int(s_plain.newton_steps), krylov_iterations=int(s_plain.krylov_iterations),
                                  solve_warm_s=warm_plain_s,
                                  lateral_gap_um=float(np.abs(np.asarray(s_plain.tracer_v) - np.asarray(s.tracer_v)).max() * 1e6)),
            lateral_max_steady_um=float(np.abs(dev_steady).max()), lateral_max_run_end_um=float(np.abs(dev_run[-1]).max()),
            longitudinal_max_steady_um=float(np.abs(du_steady).max()),
            longitudinal_max_run_end_um=float(np.abs(du_run).max()),
            lateral_gap_end_um=float(gap[-1]), settled_within_um=SETTLED, settles_at_s=t_settle,
            time_stepping_to_settle_s=None if t_settle is None else run_s * t_settle / args.t_end,
            angle_mrad_steady=float(np.asarray(s.angle)[0] * 1e3),
            angle_mrad_run_end=float(np.asarray(tr.control_u)[-1, 0] * 1e3)))
        print(rows[-1])
    tangent_s, through_s, J, through_gap = tangents(model, solver, dt, args.repeat, True)
    tangent_plain_s, _, J_plain, _ = tangents(model, solver, dt, args.repeat, False)
    tangent_rows = dict(parameters=18, preconditioned_s=tangent_s, unpreconditioned_s=tangent_plain_s,
                        through_the_solve_s=through_s, through_the_solve_relative_difference=through_gap,
                        relative_difference=float(np.abs(J - J_plain).max() / np.abs(J).max()))
    print(tangent_rows)
    program_rows = one_program(model, solver, dt, args.repeat)
    print(program_rows)
    write("steady_state", dict(tangents=tangent_rows, solve_with_tangents=program_rows,
        scene=args.scene, unknowns=model.n_unknowns, dt_s=dt, period_steps=int(ref_s.period_steps),
        t_end_s=args.t_end, run_s=run_s, aligned_solve_first_s=first, aligned_solve_warm_s=warm,
        limit_um=LIMIT_UM, device=jax.devices()[0].device_kind, cases=rows))


if __name__ == "__main__":
    main()
