"""Where the main job's time goes: ``jaxbelt tolerance`` on the default design scene, stage by
stage, with an empty compilation cache and with a warm one.

Each measurement is its own process (the CLI's persistent compilation cache in a fresh
directory: the first process fills it, the second reads it), ``--no-error-bars``. Stages: imports
and start-up, the model build (mesh, static solve), the aligned reference run, the Jacobian
(first call: compile and run; second call: run alone), one batch of eight verification runs
(first and second call) and the whole box (optimisation and verification). Run:
``OPENBLAS_NUM_THREADS=1 python benchmarks/tolerance_latency.py``. Writes
``results/tolerance_latency.json``.
"""

import json
import os
import subprocess
import sys
import tempfile

from _common import write

CHILD = r"""
import json, time
T0 = time.perf_counter()
marks = {}
def mark(name, t=[T0]):
    now = time.perf_counter(); marks[name] = now - t[0]; t[0] = now
import jax, jax.numpy as jnp, numpy as np
import jaxbelt as jb
from jaxbelt.cli import enable_compilation_cache
from jaxbelt.cli._common import load_run
from jaxbelt.design import make_study
from jaxbelt.design import tolerance as tol
from jaxbelt.design.metrics import with_limits
from jaxbelt.design.sensitivity import response_jacobian
from jaxbelt.cli._design import DESIGN_SCENE
jb.enable_x64(); enable_compilation_cache()
mark("imports_s")
scene, mesh, model, opts = load_run(DESIGN_SCENE)
jax.block_until_ready(model.chi_static); mark("model_build_s")
study = make_study(model, "lateral_max", dt=opts.dt, n_steps=opts.n_steps, integrator=opts.solver)
jax.block_until_ready(study.ref_u); mark("aligned_run_s")
limits = {"longitudinal_max": 20.0, "steering_max": 3.0}
work = with_limits(study, (("lateral_max", 20.0),) + tuple(limits.items()))
response_jacobian(work); mark("jacobian_first_s")
response_jacobian(work); mark("jacobian_again_s")
th = jnp.zeros((8, study.space.size))
np.asarray(tol._limit_values_batch(work, th)); mark("verification_batch_first_s")
np.asarray(tol._limit_values_batch(work, th)); mark("verification_batch_again_s")
res = tol.tolerance_box(study, 20.0, limits=limits); mark("tolerance_box_s")
marks["total_s"] = time.perf_counter() - T0
print(json.dumps(dict(scene=DESIGN_SCENE, n_unknowns=int(model.n_unknowns), n_steps=int(opts.n_steps),
                      parameters=int(study.space.size), iterations=int(res.iterations), stages=marks)))
"""


def main():
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "JAXBELT_CACHE_DIR": cache, "JAXBELT_COMPILATION_CACHE": "1", "OPENBLAS_NUM_THREADS": "1"}
        for label in ("empty_cache", "warm_cache"):
            r = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, check=True)
            out[label] = json.loads(r.stdout.strip().splitlines()[-1])
            print(label, json.dumps(out[label]["stages"]), flush=True)
    write("tolerance_latency", out)


if __name__ == "__main__":
    main()
