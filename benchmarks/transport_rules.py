"""The two relabelling rules of the transport step against the analytic steady state.

Idle roller of ``two-roller-1d`` moved d = 1 mm away from the drive; once running, the strain
spreads over arcs and spans: ε = d / (D + π r) in both spans, idle speed = drive speed. For
several Δt (and a refined mesh) this records the steady span strain and idle/drive speed ratio
for the "shift" and "source" rules, and the transport-weight range of each rule on
``two-roller-1d-train1`` (10 mm translation). Writes ``results/transport_rules.json``/``.png``.
"""

import dataclasses

import numpy as np

import jaxbelt as jb
from _common import RESULTS, write


def steady(transport, dt, refine=1, seconds=6.0):
    sc = jb.load_scene("two-roller-1d-idle-translated")
    sc = sc.replace(
        mesh=dataclasses.replace(sc.mesh, roller_elements=(40 * refine,) * 2, free_elements=(70 * refine,) * 2),
        time=dataclasses.replace(sc.time, dt=dt), solver=dataclasses.replace(sc.solver, transport=transport))
    mesh = jb.build_mesh(sc)
    model = jb.build_model(sc, mesh)
    integ = jb.make_solver("direct", transport=transport)
    s, tr = jb.simulate(model, integ, n_steps=int(round(seconds / dt)), dt=dt)
    u = np.asarray(integ.step(model, s, dt, integ.init(model, s, dt)).u)[:, 0]  # the solved state, before transport
    first = mesh.segment_starts[1] - 1
    ids = np.arange(first, first + mesh.free_elements[0] + 1)
    eps = float(np.mean(np.diff(u[ids]) / np.asarray(model.ell)[ids[:-1]]))
    w = np.asarray(tr.roller_velocity)[-1, :, 1]
    return {"dt": dt, "refine": refine, "strain": eps, "speed_ratio": float(w[1] / w[0])}


def main():
    exact = 1e-3 / (0.275 + np.pi * 0.05)
    rows = {rule: [steady(rule, dt, ref) for dt, ref in [(0.005, 1), (0.0025, 1), (0.00125, 2)]]
            for rule in ("shift", "source")}
    for rule, rs in rows.items():
        for r in rs:
            r["strain_rel_error"] = r["strain"] / exact - 1
            print(f"{rule:6s} dt={r['dt']:.5f} refine={r['refine']}  strain {r['strain']:.7f} "
                  f"(rel. err {r['strain_rel_error']:+.2e})  idle/drive {r['speed_ratio']:.6f}")
    weights = {}
    for rule in ("shift", "source"):
        scene = jb.load_scene("two-roller-1d-train1")
        model, dt = jb.build_model(scene), jb.RunOptions.from_scene(scene).dt
        _, tr = jb.simulate(model, jb.make_solver("direct", transport=rule), n_steps=200, dt=dt)
        tw = np.asarray(tr.transport_weights)
        weights[rule] = {"min": float(np.nanmin(tw[:, 0])), "max": float(np.nanmax(tw[:, 1])),
                         "final_belt_mass_rel_change": float(tr.belt_mass[-1] / tr.belt_mass[0] - 1)}
        print(f"train1 ({rule}): weights in [{weights[rule]['min']:.3g}, {weights[rule]['max']:.3g}], "
              f"mass change after 200 steps {weights[rule]['final_belt_mass_rel_change']:.3g}")
    write("transport_rules", {"exact_strain": exact, "steady": rows, "train1_weights": weights})

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5), constrained_layout=True)
    for rule, mk in (("shift", "o-"), ("source", "s--")):
        ax.plot([r["dt"] * 1e3 for r in rows[rule]], [r["strain"] * 1e3 for r in rows[rule]], mk, label=rule)
    ax.axhline(exact * 1e3, color="k", lw=0.8, label="d/(D+πr)")
    ax.set_xlabel("Δt [ms]")
    ax.set_ylabel("steady span strain [‰]")
    ax.set_xscale("log")
    ax.legend()
    fig.savefig(RESULTS / "transport_rules.png", dpi=120)


if __name__ == "__main__":
    main()
