"""Where the time of one step goes (the source's Figures 7.19/7.20 split), reuse and exact solvers.

``three-roller-t72`` (N = 3762). Each part of the step is jit-compiled on its own inside a
``lax.scan`` of ``--steps`` iterations whose carry feeds the part's output back into its input
(so XLA cannot hoist it out of the loop), and timed best of ``--repeat``; the whole step
(:func:`jaxbelt.timeloop.make_step`) the same way. Parts: *assembly* (roller kinematics, the
right-hand side and the matrix-free product of the predictor), *solve* (the frozen-factor
structured solve of the reuse solver; for the exact solver its per-step border update — border
first, the default, and interior first, sweeping the tilt columns — and the whole solve step,
factorisation included), *transport* (interpolation, mass flux, roller-relative and normal-entry corrections),
*outputs* (tracers, support loads, edge margins, the NaN guard); last, a whole run per step as
:func:`jaxbelt.simulate` compiles it (model and solver as the program's arguments, every step's
outputs recorded). Set ``OPENBLAS_NUM_THREADS=1``.
Writes ``results/step_profile.json``.
"""

import argparse
import time

import jax
import jax.numpy as jnp

import jaxbelt as jb
from _common import clock, write
from jaxbelt.assembly import dae_apply, dae_rhs, roller_R, static_surface_offset
from jaxbelt.integrators import StepOperator
from jaxbelt.linalg.bordered import factor_solve
from jaxbelt.run_checks import nonfinite_code
from jaxbelt.timeloop import compile_simulation, edge_margin, make_step, tracer_values
from jaxbelt.transport import transport_step_with_weights


def timed_scan(body, carry, steps, repeat):
    f = jax.jit(lambda c: jax.lax.scan(lambda c, _: (body(c), None), c, None, length=steps)[0])
    jax.block_until_ready(f(carry))
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        jax.block_until_ready(f(carry))
        best = min(best, time.perf_counter() - t0)
    return best / steps * 1e3  # ms per iteration


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--steps", type=int, default=500)
    ap.add_argument("--repeat", type=int, default=5)
    a = ap.parse_args()
    scene = jb.load_scene("three-roller-t72")
    model, dt = jb.build_model(scene), jb.RunOptions.from_scene(scene).dt
    st = jb.initial_state(model)
    reuse = jb.DirectBackwardEuler(jb.Reuse())
    exact = jb.DirectBackwardEuler(jb.KeptInterior())
    exact_sweep = jb.DirectBackwardEuler(jb.KeptInterior(border="sweep"))
    exact_full = jb.DirectBackwardEuler(jb.Structured())
    # each solver's data for the run (the frozen factors; the kept interior), as a run computes it once
    data = {"reuse": reuse.init(model, st, dt), "exact": exact.init(model, st, dt),
            "exact_sweep": exact_sweep.init(model, st, dt), "exact_full": exact_full.init(model, st, dt)}
    stencil = data["reuse"].stencil
    offset = static_surface_offset(model)
    eps = 1e-30  # feeds an output back into the input without changing it numerically

    def assembly(u):
        R = roller_R(model, u)
        F_b, F_r = dae_rhs(model, u, st.chi, dt, R)
        (Kp_b, Kp_r), _ = dae_apply(model, st.m_e, R, u + dt * st.u_dot, st.chi + dt * st.chi_dot, stencil)
        return u + eps * (F_b - Kp_b)

    rb0, rr0 = dae_rhs(model, st.u, st.chi, dt, roller_R(model, st.u))

    def solve(c):
        x_b, x_r = factor_solve(data["reuse"].linear.F, *c)
        return rb0 + eps * x_b, rr0 + eps * x_r

    def solve_step_of(solver, run_data):
        def go(s):
            new = solver.step(model, s, dt, run_data)
            return jax.tree.map(lambda x, y: x + eps * y if jnp.issubdtype(x.dtype, jnp.floating) else x, s, new)
        return go

    def border_update(solver, run_data):  # the exact mode's per-step border update, as its solver's init does it
        def go(u):
            op = StepOperator(model, st.m_e, roller_R(model, u, on_rollers=True), dt)
            return u + eps * jnp.sum(solver.init(op, run_data.linear).F.S_lu)
        return go

    def transport(u):
        out = transport_step_with_weights(model, u, st.u_dot, st.chi, st.m_e, static_offset=offset)
        return u + eps * out[0]

    def outputs(u):
        tu, tv = tracer_values(model, u)
        m = edge_margin(model, u, st.chi)
        bad = nonfinite_code(u, st.u_dot, st.chi, st.chi_dot)
        return u + eps * (jnp.sum(tu) + jnp.sum(tv) + jnp.sum(jnp.where(jnp.isfinite(m), m, 0.0)) + bad)

    rows = {}
    rows["assembly (rhs + predictor product)"] = timed_scan(assembly, st.u, a.steps, a.repeat)
    rows["solve (reuse: frozen-factor structured solve)"] = timed_scan(solve, (rb0, rr0), a.steps, a.repeat)
    rows["transport"] = timed_scan(transport, st.u, a.steps, a.repeat)
    rows["outputs (tracers, margins, NaN guard)"] = timed_scan(outputs, st.u, a.steps, a.repeat)
    step_reuse = make_step(model, reuse, dt, data["reuse"])
    rows["whole step, reuse"] = timed_scan(lambda s: step_reuse(s)[0], st, a.steps, a.repeat)
    rows["exact: border update, border first (Schur complement's tilt columns from the border rows' Green's functions)"] \
        = timed_scan(border_update(exact.linear_solver, data["exact"]), st.u, a.steps, a.repeat)
    rows["exact: border update, interior first (tilt columns' sweep, Schur complement)"] = timed_scan(
        border_update(exact_sweep.linear_solver, data["exact_sweep"]), st.u, a.steps, a.repeat)
    rows["exact solve step (kept interior, border first: border + solve)"] = timed_scan(
        solve_step_of(exact, data["exact"]), st, a.steps, a.repeat)
    rows["exact solve step (kept interior, interior first: border + solve)"] = timed_scan(
        solve_step_of(exact_sweep, data["exact_sweep"]), st, a.steps, a.repeat)
    rows["exact solve step, full factorisation every step"] = timed_scan(
        solve_step_of(exact_full, data["exact_full"]), st, a.steps // 5, a.repeat)
    step_exact = make_step(model, exact, dt, data["exact"])
    rows["whole step, exact"] = timed_scan(lambda s: step_exact(s)[0], st, a.steps, a.repeat)
    # a run as jaxbelt.simulate compiles it: the model and the solver are arguments of the program
    # (not constants folded into it) and every step's outputs are recorded
    run = compile_simulation(model, reuse, n_steps=a.steps, dt=dt)
    rows["whole run per step, reuse (outputs recorded, as simulate runs it)"] = 1e3 / a.steps * min(
        clock(lambda: run(model, dt)[0].u)[0] for _ in range(a.repeat + 1))
    for k, v in rows.items():
        print(f"{k:72s} {v:7.3f} ms", flush=True)
    write("step_profile", {"scene": "three-roller-t72", "n_unknowns": model.n_unknowns,
                           "ms_per_step": rows, "steps": a.steps, "repeat": a.repeat})


if __name__ == "__main__":
    main()
