"""Where the time of one step goes (the source's Figures 7.19/7.20 split), reuse and exact solvers.

``three-roller-t72`` (N = 3762). Each part of the step is jit-compiled on its own inside a
``lax.scan`` of ``--steps`` iterations whose carry feeds the part's output back into its input
(so XLA cannot hoist it out of the loop), and timed best of ``--repeat``; the whole step
(:func:`jaxbelt.timeloop.make_step`) the same way. Parts: *assembly* (roller kinematics, the
right-hand side and the matrix-free product of the predictor), *solve* (the frozen-factor
structured solve of the reuse solver; for the exact solver the whole solve step, factorisation
included), *transport* (interpolation, mass flux, roller-relative and normal-entry corrections),
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
from _common import write
import equinox as eqx

from jaxbelt.assembly import dae_apply, dae_rhs, roller_R, static_surface_offset
from jaxbelt.bench._common import clock
from jaxbelt.integrators import DirectBackwardEuler, ReusedFactorisationBackwardEuler
from jaxbelt.linalg.bordered import factor_solve, refactorise_border
from jaxbelt.timeloop import make_step, tracer_values
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
    model = jb.compile_scene(jb.load_scene("three-roller-t72"))
    st = jb.initial_state(model)
    reuse = ReusedFactorisationBackwardEuler.for_model(model).prepare(model)
    exact = DirectBackwardEuler.for_model(model).prepare(model)  # the kept interior, as a run uses it
    exact_full = DirectBackwardEuler("structured", keep_interior=False)
    offset = static_surface_offset(model)
    dt = model.dt
    eps = 1e-30  # feeds an output back into the input without changing it numerically

    def assembly(u):
        R = roller_R(model, u)
        F_b, F_r = dae_rhs(model, u, st.chi, R)
        (Kp_b, Kp_r), _ = dae_apply(model, st.m_e, R, u + dt * st.u_dot, st.chi + dt * st.chi_dot, reuse.stencil)
        return u + eps * (F_b - Kp_b)

    rb0, rr0 = dae_rhs(model, st.u, st.chi, roller_R(model, st.u))

    def solve(c):
        x_b, x_r = factor_solve(reuse.factors, *c)
        return rb0 + eps * x_b, rr0 + eps * x_r

    def solve_step_of(integ):
        def go(s):
            new = integ.solve_step(model, s)
            return jax.tree.map(lambda x, y: x + eps * y if jnp.issubdtype(x.dtype, jnp.floating) else x, s, new)
        return go

    ref = exact.reference

    def border(u):  # the exact mode's per-step refactorisation (tilt columns, Schur complement)
        R = roller_R(model, u)
        cols = jnp.asarray(exact.lever_columns)
        C = ref.A.C.at[:, :, cols].set(jnp.where(model.is_constraint[:, :, None], -dt**2 * R[:, :, cols], 0.0))
        A = eqx.tree_at(lambda a: a.C, ref.A, C)
        F = refactorise_border(A, ref.F, ref.S, exact.lever_columns, exact.lever_rows)
        return u + eps * jnp.sum(F.S_lu)

    def transport(u):
        out = transport_step_with_weights(model, u, st.u_dot, st.chi, st.m_e, static_offset=offset)
        return u + eps * out[0]

    def outputs(u):
        tu, tv = tracer_values(model, u)
        from jaxbelt.timeloop import edge_margin, nonfinite_code

        m = edge_margin(model, u, st.chi)
        bad = nonfinite_code(u, st.u_dot, st.chi, st.chi_dot)
        return u + eps * (jnp.sum(tu) + jnp.sum(tv) + jnp.sum(jnp.where(jnp.isfinite(m), m, 0.0)) + bad)

    rows = {}
    rows["assembly (rhs + predictor product)"] = timed_scan(assembly, st.u, a.steps, a.repeat)
    rows["solve (reuse: frozen-factor structured solve)"] = timed_scan(solve, (rb0, rr0), a.steps, a.repeat)
    rows["transport"] = timed_scan(transport, st.u, a.steps, a.repeat)
    rows["outputs (tracers, margins, NaN guard)"] = timed_scan(outputs, st.u, a.steps, a.repeat)
    step_reuse = make_step(model, reuse)
    rows["whole step, reuse"] = timed_scan(lambda s: step_reuse(s)[0], st, a.steps, a.repeat)
    rows["exact: border refactorisation (tilt columns' sweep, Schur complement)"] = timed_scan(
        border, st.u, a.steps, a.repeat)
    rows["exact solve step (kept interior: border + solve)"] = timed_scan(solve_step_of(exact), st, a.steps, a.repeat)
    rows["exact solve step, full factorisation every step"] = timed_scan(solve_step_of(exact_full), st,
                                                                         a.steps // 5, a.repeat)
    step_exact = make_step(model, exact)
    rows["whole step, exact"] = timed_scan(lambda s: step_exact(s)[0], st, a.steps, a.repeat)
    # a run as jaxbelt.simulate compiles it: the model and the solver are arguments of the program
    # (not constants folded into it) and every step's outputs are recorded
    from jaxbelt.timeloop import _run_jit

    integ_reuse = ReusedFactorisationBackwardEuler.for_model(model)
    run = _run_jit.lower(model, integ_reuse, st, a.steps).compile()
    rows["whole run per step, reuse (outputs recorded, as simulate runs it)"] = 1e3 / a.steps * min(
        clock(lambda: run(model, integ_reuse, st, a.steps)[0].u)[0] for _ in range(a.repeat + 1))
    for k, v in rows.items():
        print(f"{k:72s} {v:7.3f} ms", flush=True)
    write("step_profile", {"scene": "three-roller-t72", "n_unknowns": model.n_unknowns,
                           "ms_per_step": rows, "steps": a.steps, "repeat": a.repeat})


if __name__ == "__main__":
    main()
