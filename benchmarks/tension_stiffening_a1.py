"""What tension stiffening changes on the source's Appendix A.1 runs (and on Appendix C).

Each of the twelve ``three-roller-a1-run*`` scenes (and ``three-roller-tension``, roller 2 pulled
with 200 N) is run over its whole time span (100 s, 5000 steps, reuse solver) with
``[solver] tension_stiffening`` on and off; recorded: the largest tracer difference in u and v
over the run, relative to the run's largest tracer displacement, and the Frobenius norm of the
initial-stress stiffness that was added. The source's scenes carry no pre-tension and the aligned
machine's static solution is stress-free, so there the stiffening is zero and the runs agree to
round-off: the source's tables stay reproducible with the default on.
Writes ``results/tension_stiffening_a1.json``.
"""

import dataclasses
import time

import jax.numpy as jnp
import numpy as np

import jaxbelt as jb
from _common import write


def run(name, stiffening, steps=None):
    sc = jb.load_scene(name)
    sc = dataclasses.replace(sc, solver=dataclasses.replace(sc.solver, tension_stiffening=stiffening,
                                                             linear_solver="reuse"))
    m, opts = jb.build_model(sc), jb.RunOptions.from_scene(sc)
    _, tr = jb.simulate(m, **opts.replace(n_steps=steps or opts.n_steps))
    return m, np.asarray(tr.tracer_u), np.asarray(tr.tracer_v)


def main():
    rows = []
    for name in [f"three-roller-a1-run{k}" for k in range(1, 13)] + ["three-roller-tension"]:
        t0 = time.perf_counter()
        m_on, u_on, v_on = run(name, True)
        m_off, u_off, v_off = run(name, False)
        k_sigma = float(jnp.sqrt(sum(jnp.sum((a - b) ** 2) for a, b in
                                     ((m_on.K_diag, m_off.K_diag), (m_on.K_lower, m_off.K_lower)))))
        k_norm = float(jnp.sqrt(jnp.sum(m_off.K_diag ** 2) + jnp.sum(m_off.K_lower ** 2)))
        scale = max(np.max(np.abs(u_off)), np.max(np.abs(v_off)), 1e-30)
        row = {"scene": name, "K_sigma_over_K": k_sigma / k_norm,
               "max_du_um": float(np.max(np.abs(u_on - u_off))) * 1e6,
               "max_dv_um": float(np.max(np.abs(v_on - v_off))) * 1e6,
               "max_tracer_displacement_um": scale * 1e6, "wall_s": time.perf_counter() - t0}
        rows.append(row)
        print(row, flush=True)
    write("tension_stiffening_a1", {"rows": rows})


if __name__ == "__main__":
    main()
