"""float32 against float64, end to end, on the default scenes.

Each precision runs in its own process (``JAX_ENABLE_X64`` is process-wide in JAX; jaxbelt
computes in float32 unless it is on): ``two-roller-1d`` for 1000
steps and ``three-roller-t72`` for its whole 100 s (5000 steps, reuse solver); recorded: the
largest tracer difference (mm), the largest tracer displacement (mm), the belt-mass drift in
each precision, and the wall time of the run (compile apart). Writes ``results/float32.json``.
"""

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

from _common import write

CHILD = r"""
import json, sys, time
import numpy as np
import jax, jaxbelt as jb
name, steps, solver, out = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
sc = jb.load_scene(name)
m, opts = jb.build_model(sc), jb.RunOptions.from_scene(sc).replace(n_steps=steps)
if solver != "-":
    opts = opts.replace(solver=jb.make_solver("direct", solver))
_, tr = jb.simulate(m, **opts)          # compile + run
t0 = time.perf_counter()
_, tr = jax.block_until_ready(jb.simulate(m, **opts))
wall = time.perf_counter() - t0
mass = np.asarray(tr.belt_mass, np.float64)
np.savez(out, u=np.asarray(tr.tracer_u, np.float64),
         v=np.asarray(tr.tracer_v, np.float64) if tr.tracer_v is not None else np.zeros(1))
print(json.dumps({"dtype": str(tr.tracer_u.dtype), "wall_s": wall, "mass_drift": float(np.max(np.abs(mass / mass[0] - 1)))}))
"""


def run(name, steps, solver, x64):
    with tempfile.TemporaryDirectory() as d:
        out = str(Path(d) / "r.npz")
        env = {**os.environ, "JAX_ENABLE_X64": "1" if x64 else "0"}
        r = subprocess.run([sys.executable, "-c", CHILD, name, str(steps), solver, out], env=env,
                           capture_output=True, text=True, check=True)
        info = json.loads(r.stdout.strip().splitlines()[-1])
        data = np.load(out)
        return info, data["u"], data["v"]


def main():
    rows = []
    for name, steps, solver in (("two-roller-1d", 1000, "-"), ("three-roller-t72", 5000, "reuse")):
        i64, u64, v64 = run(name, steps, solver, True)
        i32, u32, v32 = run(name, steps, solver, False)
        row = {"scene": name, "steps": steps, "solver": solver, "dtype_64": i64["dtype"], "dtype_32": i32["dtype"],
               "max_tracer_error_um": float(max(np.abs(u32 - u64).max(), np.abs(v32 - v64).max()) * 1e6),
               "max_tracer_displacement_um": float(max(np.abs(u64).max(), np.abs(v64).max()) * 1e6),
               "mass_drift_64": i64["mass_drift"], "mass_drift_32": i32["mass_drift"],
               "wall_s_64": i64["wall_s"], "wall_s_32": i32["wall_s"]}
        rows.append(row)
        print(row, flush=True)
    write("float32", {"rows": rows})


if __name__ == "__main__":
    main()
