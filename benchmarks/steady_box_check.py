"""The steady tolerance box checked by time-stepping, and beside the 16–20 s window box.

1. The worst verification corner of the steady box in ``results/design_steady.json`` (the main
   job's own output) run by time-stepping, the aligned machine beside it with the same sensor seed,
   long enough to settle: the lateral and longitudinal deviation and the actuator angle over the
   last 4 s of each 20 s block until two blocks agree within 0.5 % of the limit; reported beside
   the steady solve's values at that corner.
2. ``jaxbelt tolerance --window 4 --no-error-bars --json``: the box judged over 16–20 s of a 20 s
   run, the question the design commands answered before steady operation, for the comparison in
   docs/tolerance.md.

Run after ``design_steady.py``: ``OPENBLAS_NUM_THREADS=1 python benchmarks/steady_box_check.py``.
Writes ``results/steady_box_check.json``.
"""

import contextlib
import io
import json
import time

import jax.numpy as jnp
import numpy as np

import jaxbelt as jb
from _common import RESULTS, load, write
from jaxbelt.cli import main as cli
from jaxbelt.misalignment import aligned, apply, parameter_space

BLOCK_S, WINDOW_S, MAX_BLOCKS = 20.0, 4.0, 20


def window_box():
    buf = io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(buf):
        rc = cli(["tolerance", "--window", str(WINDOW_S), "--no-error-bars", "--json"])
    assert rc == 0
    return json.loads(buf.getvalue()), time.perf_counter() - t0


def main():
    steady = json.loads((RESULTS / "design_steady.json").read_text())["three-roller-steered"]
    limit = steady["limit_um"]
    worst = max((r for r in steady["verification"] if r["kind"] == "worst corner"), key=lambda r: r["full_um"])
    model, opts = load("three-roller-steered")
    model = aligned(model)
    space = parameter_space(model)
    theta = np.zeros(space.size)
    for k, label in enumerate(space.labels()):
        roller, comp = label.split(":")
        group = "translation_mm" if comp.startswith("d") else "rotation_mrad"
        theta[k] = worst["corner"][roller][group]["xyz".index(comp[1])]
    corner = apply(model, space, jnp.asarray(theta))
    n = int(round(BLOCK_S / opts.dt))
    w = int(round(WINDOW_S / opts.dt))
    states = [None, None]
    blocks, settled = [], False
    for b in range(MAX_BLOCKS):
        out = []
        for i, m in enumerate((model, corner)):
            states[i], tr = jb.simulate(m, opts.solver, n_steps=n, dt=opts.dt, y0=states[i])
            out.append(tr)
        du = (np.asarray(out[1].tracer_u) - np.asarray(out[0].tracer_u))[-w:] * 1e6
        dv = (np.asarray(out[1].tracer_v) - np.asarray(out[0].tracer_v))[-w:] * 1e6
        angle = np.abs(np.asarray(out[1].control_u)[-w:]).max() * 1e3
        blocks.append(dict(t_end_s=(b + 1) * BLOCK_S, lateral_max_um=float(np.abs(dv).max()),
                           longitudinal_max_um=float(np.abs(du).max()), steering_max_mrad=float(angle)))
        print(blocks[-1])
        settled = b > 0 and max(abs(blocks[-1][k] - blocks[-2][k])
                                for k in ("lateral_max_um", "longitudinal_max_um")) <= 0.005 * limit
        if settled:
            break
    win, win_s = window_box()
    write("steady_box_check", dict(
        corner=worst["corner"], steady_by_limit=worst.get("full_by_limit"), time_stepped_blocks=blocks,
        settled=bool(settled), settled_within_um=0.005 * limit, window_box=win,
        window_command_s=win_s))


if __name__ == "__main__":
    main()
