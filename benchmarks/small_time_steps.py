"""Small time steps on a fixed grid: the impulsive start against a running start.

Every built-in machine family — ``two-roller-1d``, ``two-roller-1d-idle-translated`` (idle roller
1 mm out), ``three-roller-1d``, ``three-roller`` (2D), ``three-roller-t72`` (2D, three rollers
misaligned), ``four-roller-external`` (2D, an external
roller) and ``three-roller-steered`` (2D, its steering loop closed) — runs 0.2 s from the static
equilibrium at the scene's Δt and at Δt/10, Δt/100 and (1D) Δt/1000, once from rest (model
specification §2: belt and idle rollers at rest, the drive at speed) and once running
(:func:`jaxbelt.initial_state` with ``start="running"``). Recorded: the Courant number, the
largest departure of an idle roller's surface speed from the belt speed at the end (no slip),
the swing :func:`jaxbelt.state.start_swing` predicts is left, the largest tracer displacement
over the run, and the gap between successive levels at the end. Also the idle roller's swing
after a start from rest at Δt = 2e-5 s against the torsional frequency of its inertia on the
spans, ``√(2 EA / L / (m_r / 2))``.

Run: ``python benchmarks/small_time_steps.py`` (``--only SCENE ...``: re-run those, keep the rest). Writes ``results/small_time_steps.json``.
"""

import math

import numpy as np

import jaxbelt as jb
from jaxbelt.mesh import build_mesh
from jaxbelt.state import start_swing
from jaxbelt.run_checks import belt_speed
from _common import load, write

T_END = 0.2
SCENES = {"two-roller-1d": 1000, "two-roller-1d-idle-translated": 1000, "three-roller-1d": 1000,
          "three-roller": 100, "three-roller-t72": 100, "four-roller-external": 100,
          "three-roller-steered": 100}  # the finest level


def idle_slip(scene, model, rv):
    """The largest ``|ω r / V − 1|`` over the idle (and tension) rollers at the end of a run."""
    az = model.dofs.index("az")
    V = belt_speed(model)
    return float(max(abs(abs(rv[j, az]) * r.radius / V - 1.0) for j, r in enumerate(scene.rollers)
                     if r.role != "drive"))


def runs(name, start, finest):
    scene = jb.load_scene(name)
    model, opts = load(scene)
    mesh = build_mesh(scene)
    y0 = jb.initial_state(model, start=start)
    rows, prev = [], None
    for k in [k for k in (1, 10, 100, 1000) if k <= finest]:
        dt = opts.dt / k
        n = int(round(T_END / dt))
        _, tr = jb.simulate(model, opts.solver, n_steps=n, dt=dt, y0=y0, saveat=jb.SaveAt(every=max(1, n // 200)))
        u = np.asarray(tr.tracer_u) * 1e6
        rv = np.asarray(tr.roller_velocity)[-1]
        row = {"dt_s": dt, "courant": float(belt_speed(model) * dt / float(np.min(np.asarray(model.ell)))),
               "idle_slip": idle_slip(scene, model, rv),
               "max_abs_tracer_u_um": float(np.abs(u).max())}
        if start == "rest":
            row["start_swing_left"] = max(left for _, _, left in start_swing(scene, mesh, dt, n))
        if prev is not None:
            row["gap_to_previous_level_um"] = float(np.abs(u[-1] - prev).max())
        prev = u[-1]
        rows.append(row)
        print(name, start, row, flush=True)
    return rows


def swing():
    scene = jb.load_scene("two-roller-1d")
    model, opts = load(scene)
    dt, n = 2e-5, 2500
    _, tr = jb.simulate(model, opts.solver, n_steps=n, dt=dt)
    w = np.asarray(tr.roller_velocity)[:, 1, -1]
    b, r = scene.belt, scene.rollers[1]
    EA = b.youngs_modulus * b.width * b.thickness
    span = math.hypot(*np.subtract(r.center, scene.rollers[0].center))
    omega_t = math.sqrt(2 * EA / span / (0.5 * r.mass))
    up = np.flatnonzero((w[:-1] < 10.0) & (w[1:] >= 10.0))
    f = 1.0 / (np.mean(np.diff(up)) * dt)
    return {"dt_s": dt, "frequency_hz": float(f), "torsional_frequency_hz": omega_t / (2 * math.pi),
            "idle_speed_min_rad_s": float(w.min()), "idle_speed_max_rad_s": float(w.max()),
            "idle_speed_mean_rad_s": float(np.mean(w[up[0]:up[-1]])),
            # Backward Euler's amplification of an undamped mode: 1 / sqrt(1 + (ω Δt)²) per step
            "swing_left_after_one_step_at_scene_dt": 1.0 / math.sqrt(1.0 + (omega_t * opts.dt) ** 2),
            "swing_decay_rate_per_s_at_dt_over_1000": omega_t**2 * (opts.dt / 1000) / 2}


def main():
    import argparse
    import json
    from pathlib import Path

    ap = argparse.ArgumentParser()
    ap.add_argument("--only", nargs="*", default=None, help="re-run these scenes, keep the others' results")
    only = ap.parse_args().only
    path = Path(__file__).parent / "results" / "small_time_steps.json"
    out = {"t_end_s": T_END, "finest_level": SCENES, "runs": {}}
    if only:
        out["runs"] = json.loads(path.read_text())["runs"]
    for scene, finest in SCENES.items():
        if only and scene not in only:
            continue
        for start in ("rest", "running"):
            out["runs"][f"{scene} {start}"] = runs(scene, start, finest)
    out["runs"] = {f"{sc} {st}": out["runs"][f"{sc} {st}"] for sc in SCENES for st in ("rest", "running")}
    out["swing"] = swing()
    print(out["swing"])
    write("small_time_steps", out)


if __name__ == "__main__":
    main()
