"""Steering-loop tuning against the classical rules: ``jaxbelt.steering.tuning.tune`` (Adam through
the whole closed-loop run, GM ≥ 6 dB and PM ≥ 45°) for both objectives on one scene, with SIMC and
Ziegler–Nichols run through the same full model, and the gradient against central differences at
the scene's own gains.

Run: ``python benchmarks/tuning.py [--scene two-roller-steered] [--iterations 40]``.
Writes ``results/tuning.json``.
"""

import argparse

import numpy as np

from _common import load, write
from jaxbelt.steering import response as loop_response, tuning


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="two-roller-steered")
    ap.add_argument("--iterations", type=int, default=40)
    args = ap.parse_args()
    model, opts = load(args.scene)
    response = loop_response.open_loop_response(model, opts, t_end=max(opts.t_end, 30.0))
    g = np.array([float(model.control.kp[0]), float(model.control.ki[0])])
    _, grad = tuning.objective_and_grad(model, g, opts)
    fd = []
    for i in range(2):
        h = np.zeros(2)
        h[i] = 1e-4 * g[i]
        fd.append((float(tuning.objective(model, g + h, opts)) - float(tuning.objective(model, g - h, opts))) / (2 * h[i]))
    out = {"scene": args.scene, "t_end_s": opts.t_end, "dt_s": opts.dt,
           "gradient_check": {"gains": g.tolist(), "reverse_mode": grad.tolist(), "central_difference": fd,
                              "relative_difference": (np.abs(grad - fd) / np.abs(fd)).tolist()}}
    for kind in tuning.OBJECTIVES:
        r = tuning.tune(model, opts, kind=kind, iterations=args.iterations, response=response, scene_name=args.scene,
                        progress=True)
        out[kind] = r.to_dict()
        rows = [r.start, r.tuned, *r.classical]
        print(f"{kind}: " + "; ".join(f"{p.rule} kp {p.kp_mrad_per_mm:.3g} ki {p.ki_mrad_per_mm_s:.3g} "
                                       f"obj {p.objective:.4g} GM {p.gain_margin_db:.3g}/{p.response_gain_margin_db:.3g} dB "
                                       f"PM {p.phase_margin_deg:.3g}/{p.response_phase_margin_deg:.3g}°" for p in rows))
    write("tuning", out)


if __name__ == "__main__":
    main()
