"""Why jaxbelt sets ``OPENBLAS_NUM_THREADS=1`` by default: LAPACK calls behind ``jnp.linalg`` with
one OpenBLAS thread and with as many as cores, each in its own process (the variable is read when
OpenBLAS loads). Times: a 448 × 100 SVD and a DMD prediction (rank 51, 300 steps) on the 1D
scene, best of 5 after a compiling call. The difference shows when the cores are busy (another
job, or XLA's own threads); on an idle machine both are fast. Run:
``python benchmarks/openblas_threads.py``; writes ``results/openblas_threads.json``.
"""

import json
import os
import subprocess
import sys

from _common import write

CHILD = r"""
import json, time, jax, jax.numpy as jnp, jaxbelt as jb
from jaxbelt import rom
m = jb.load_model("two-roller-1d-train1")
Z = rom.collect_first_order(m, 100)[1]
fit = rom.fit_dmd(Z).stable()
svd = jax.jit(lambda X: jnp.linalg.svd(X, full_matrices=False))
pred = jax.jit(lambda f, x: f.predict(x, 300))
def best(fn, *a):
    jax.block_until_ready(fn(*a)); ts = []
    for _ in range(5):
        t0 = time.perf_counter(); jax.block_until_ready(fn(*a)); ts.append(time.perf_counter() - t0)
    return min(ts)
print(json.dumps({"svd_448x100_s": best(svd, Z), "dmd_predict_s": best(pred, fit, Z[:, -1]),
                  "load": os.getloadavg()[0] if hasattr(os, "getloadavg") else None}))
""".replace("import json, time", "import os, json, time")


def main():
    rows = {}
    for threads in ("1", str(os.cpu_count())):
        r = subprocess.run([sys.executable, "-c", CHILD], env={**os.environ, "OPENBLAS_NUM_THREADS": threads},
                           capture_output=True, text=True, check=True)
        rows[f"OPENBLAS_NUM_THREADS={threads}"] = json.loads(r.stdout.strip().splitlines()[-1])
        print(threads, rows[f"OPENBLAS_NUM_THREADS={threads}"], flush=True)
    write("openblas_threads", {"rows": rows})


if __name__ == "__main__":
    main()
