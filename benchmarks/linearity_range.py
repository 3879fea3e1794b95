"""Where the model's linearisation in the misalignments breaks: the linearity error against size.

``three-roller`` (n_η = 3, 2 s = 100 steps, reuse solver), one component of roller 2 at a time
(rotation about x, y, z; translation along x, y, z) at sizes from 1e-9 to 0.1 (rad or m). The
response is the tracer deviation (u and v) from the aligned machine at the last step; its
linearity error is ``‖r(a)/a − r(a₀)/a₀‖ / ‖r(a₀)/a₀‖`` against the slope at a₀ = 1e-6. The
model is exact in the static rotation (x → y → z) and linear in its increments, with the lever
arm lagged one step, so the error grows with the misalignment; the scene checks in
``jaxbelt.scene`` warn and refuse at the sizes this measurement sets (README, "Stability").
Writes ``results/linearity_range.json`` and ``.png``.
"""

import copy
import tomllib
from importlib import resources

import jax.numpy as jnp
import numpy as np

import jaxbelt as jb
from _common import RESULTS, write

SIZES = np.logspace(-9, -1, 17)
COMPONENTS = [("rotation", 0), ("rotation", 1), ("rotation", 2), ("translation", 0), ("translation", 1),
              ("translation", 2)]


def main():
    d = copy.deepcopy(tomllib.loads((resources.files("jaxbelt") / "scenes" / "three-roller.toml").read_text()))
    d["mesh"].update(n_eta=3)
    d["time"].update(t_end_s=2.0)
    d["solver"] = {"linear_solver": "reuse"}
    scene = jb.scene_from_dict(d)
    model, opts = jb.build_model(scene), jb.RunOptions.from_scene(scene)
    _, ref = jb.simulate(model, **opts)
    r0 = np.concatenate([np.asarray(ref.tracer_u[-1]), np.asarray(ref.tracer_v[-1])])

    def response(kind, axis, a):
        arr = jnp.zeros((3, 3)).at[1, axis].set(a)
        m = jb.with_misalignment(model, **{kind: arr})
        _, tr = jb.simulate(m, **opts, check=False)
        r = np.concatenate([np.asarray(tr.tracer_u[-1]), np.asarray(tr.tracer_v[-1])])
        return r - r0, bool(np.any(np.asarray(tr.nonfinite)))

    rows = []
    for kind, axis in COMPONENTS:
        slope0 = response(kind, axis, 1e-6)[0] / 1e-6
        errs = []
        for a in SIZES:
            r, bad = response(kind, axis, float(a))
            err = float(np.linalg.norm(r / a - slope0) / max(np.linalg.norm(slope0), 1e-300)) if not bad else np.inf
            errs.append(err)
            print(f"{kind} {'xyz'[axis]} {a:8.1e}: linearity error {err:.3e}", flush=True)
        rows.append({"component": f"{kind} {'xyz'[axis]}", "size": SIZES.tolist(), "linearity_error": errs,
                     "slope_norm": float(np.linalg.norm(slope0))})
    write("linearity_range", {"scene": "three-roller n_eta=3, 2 s, roller 2", "rows": rows})

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    for r in rows:
        if r["slope_norm"] > 0:
            ax.loglog(r["size"], np.maximum(r["linearity_error"], 1e-16), "o-", ms=3, label=r["component"])
    ax.set_xlabel("misalignment (rad or m)")
    ax.set_ylabel("linearity error of the tracer response")
    ax.set_title("three-roller, roller 2: where the linearisation breaks")
    ax.legend(fontsize=8)
    fig.savefig(RESULTS / "linearity_range.png", dpi=120)


if __name__ == "__main__":
    main()
