"""Command line: ``jaxbelt demo | scenes | info | simulate``.

Every user error (bad scene, bad option) ends with a one-line message on stderr and exit code 2,
never a traceback.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np

DEFAULT_SCENE = "two-roller-1d"


class UsageError(Exception):
    pass


class SimulationError(Exception):
    pass


def _load(scene_arg, t_end=None, dt=None, integrator=None, transport=None, linear_solver=None):
    from .scene import load_scene

    scene = load_scene(scene_arg)
    if t_end is not None or dt is not None:
        t = scene.time
        t_end = t.t_end if t_end is None else t_end
        dt = t.dt if dt is None else dt
        for key, v in (("--t-end", t_end), ("--dt", dt)):
            if not np.isfinite(v) or v <= 0:
                raise UsageError(f"{key} = {v}: must be a positive number")
        if t_end < dt:
            raise UsageError(f"--t-end = {t_end}: shorter than one step (dt = {dt})")
        scene = scene.replace(time=dataclasses.replace(t, t_end=float(t_end), dt=float(dt)))
    if integrator is not None:
        scene = scene.replace(solver=dataclasses.replace(scene.solver, integrator=integrator))
    if transport is not None:
        scene = scene.replace(solver=dataclasses.replace(scene.solver, transport=transport))
    if linear_solver is not None:
        scene = scene.replace(solver=dataclasses.replace(scene.solver, linear_solver=linear_solver))
    return scene


def bandwidth(K) -> int:
    """Half-bandwidth of the belt part of ``K`` in the natural column ordering (cyclic corners
    and the roller border excluded)."""
    b = K.block
    bw = 0
    for blocks, shift in ((K.diag, 0), (K.upper, b), (K.lower, -b)):
        nz = np.argwhere(np.any(np.asarray(blocks) != 0, axis=0))
        if len(nz):
            bw = max(bw, int(np.max(np.abs(nz[:, 1] - nz[:, 0] + shift))))
    return bw


def model_info(scene, mesh, model) -> dict:
    """What the compiled model contains (``jaxbelt info``)."""
    from .assembly import dae_matrices

    K, _ = dae_matrices(model, model.m_e0)
    dyn = np.asarray(model.dynamic).reshape(model.n_rollers, len(model.dofs))
    chi = np.asarray(model.chi_static).reshape(dyn.shape)
    rollers = []
    for j, r in enumerate(scene.rollers):
        seg = mesh.path.segments[2 * j]
        rollers.append(dict(
            name=r.name, role=r.role, side="external" if r.external else "internal",
            center_mm=[c * 1e3 for c in r.center], radius_mm=r.radius * 1e3,
            wrap_deg=float(np.degrees(seg.wrap)), arc_mm=seg.length * 1e3,
            elements=int(mesh.roller_elements[j]),
            dynamic_dofs=[d for d, f in zip(model.dofs, dyn[j]) if f],
            prescribed={d: float(v) for d, v, f in zip(model.dofs, chi[j], dyn[j]) if not f and d != "az"},
            speed_m_s=r.speed if r.role == "drive" else None,
        ))
    segments = [dict(kind=s.kind, name=s.name, length_mm=s.length * 1e3,
                     elements=int(mesh.roller_elements[s.index] if s.kind == "roller" else mesh.free_elements[s.index]))
                for s in mesh.path.segments]
    n_alg = model.n_algebraic
    return dict(
        scene=scene.name, kind=scene.kind, description=scene.description,
        n_unknowns=model.n_unknowns, n_algebraic=n_alg, n_dynamic=model.n_unknowns - n_alg,
        n_belt_dofs=model.n_xi * model.block, n_roller_dofs=model.n_roller_dofs,
        n_xi=model.n_xi, n_eta=mesh.n_eta, block_size=model.block, bandwidth=bandwidth(K),
        path_length_mm=mesh.length * 1e3, element_length_mm=[float(mesh.ell.min() * 1e3), float(mesh.ell.max() * 1e3)],
        dt_s=model.dt, t_end_s=scene.time.t_end, n_steps=model.n_steps,
        cfl=float(max((r.speed for r in scene.rollers if r.role == "drive"), default=0) * model.dt / mesh.ell.min()),
        integrator=model.integrator, linear_solver=model.linear_solver, transport=model.transport,
        n_tracers=model.n_tracers, output_every=model.every, full_fields=model.full_fields,
        pretension_strain=float(mesh.length / (scene.belt.length or mesh.length) - 1.0),
        dynamic_roller_rows=int(np.sum(dyn)), rollers=rollers, segments=segments,
    )


def _print_info(info):
    print(f"scene {info['scene']} ({info['kind']}): {info['description']}")
    print(f"  unknowns N = {info['n_unknowns']}  (belt {info['n_belt_dofs']} + rollers {info['n_roller_dofs']}); "
          f"algebraic {info['n_algebraic']}, dynamic {info['n_dynamic']} (= N after elimination)")
    print(f"  grid n_xi × n_eta = {info['n_xi']} × {info['n_eta']}, block size {info['block_size']}, "
          f"bandwidth {info['bandwidth']}, path {info['path_length_mm']:.3f} mm, "
          f"elements {info['element_length_mm'][0]:.3f}–{info['element_length_mm'][1]:.3f} mm")
    print(f"  time dt = {info['dt_s']:g} s, {info['n_steps']} steps to {info['t_end_s']:g} s, CFL number "
          f"{info['cfl']:.3f}; integrator {info['integrator']} ({info['linear_solver']} solve), "
          f"transport {info['transport']}")
    print(f"  outputs: {info['n_tracers']} tracers every {info['output_every']} step(s)"
          f"{', full fields' if info['full_fields'] else ''}; pre-tension strain {info['pretension_strain']:.3g}")
    for r in info["rollers"]:
        print(f"  roller {r['name']!r}: {r['role']}, {r['side']}, r = {r['radius_mm']:g} mm at {r['center_mm']}, "
              f"wrap {r['wrap_deg']:.1f}° ({r['elements']} elements), dynamic DOFs {r['dynamic_dofs'] or '-'}"
              + (f", prescribed {r['prescribed']}" if any(r["prescribed"].values()) else ""))
    for s in info["segments"]:
        print(f"    {s['kind']:6s} {s['name']:24s} {s['length_mm']:10.3f} mm  {s['elements']:4d} elements")


def _summary(scene, model, traj, wall, compile_s):
    t = np.asarray(traj.t)
    tu = np.asarray(traj.tracer_u)
    rv = np.asarray(traj.roller_velocity)
    mass = np.asarray(traj.belt_mass)
    tw = np.asarray(traj.transport_weights)
    az = model.dofs.index("az")
    return dict(
        scene=scene.name, integrator=model.integrator, n_steps=int(round(t[-1] / model.dt)), t_end_s=float(t[-1]),
        n_unknowns=model.n_unknowns, wall_s=wall, compile_s=compile_s,
        tracer_u_max_abs_mm=float(np.max(np.abs(tu)) * 1e3), tracer_u_final_mm=(tu[-1] * 1e3).round(6).tolist(),
        roller_speed_m_s={r.name: float(abs(rv[-1, j, az]) * r.radius) for j, r in enumerate(scene.rollers)},
        belt_mass_kg=float(mass[-1]), belt_mass_rel_drift=float(np.max(np.abs(mass - mass[0])) / mass[0]),
        transport=model.transport, transport_weight_range=[float(np.min(tw[:, 0])), float(np.max(tw[:, 1]))],
    )


def cmd_simulate(args, demo=False):
    from . import compile_scene, simulate_with_progress
    from .integrators import make_integrator
    from .mesh import build_mesh

    scene = _load(args.scene, args.t_end, args.dt, args.integrator, getattr(args, "transport", None),
                  getattr(args, "solver", None))
    mesh = build_mesh(scene)
    model = compile_scene(scene, mesh)
    integrator = make_integrator(model.integrator, model)
    progress = getattr(args, "progress", False) or (not args.json and sys.stderr.isatty())
    _, traj, timing = simulate_with_progress(model, integrator, progress=progress)
    wall, compile_s = timing["run_s"], timing["compile_s"]
    s = _summary(scene, model, traj, wall, compile_s)
    if not np.all(np.isfinite(np.asarray(traj.tracer_u))):
        k = int(np.argmax(~np.all(np.isfinite(np.asarray(traj.tracer_u)), axis=1)))
        raise SimulationError(f"the simulation diverged (non-finite displacement at t = {float(traj.t[k]):g} s); "
                              f"check the transport weights {s['transport_weight_range']} and the time step")
    if args.out:
        out = Path(args.out)
        np.savez(
            out, t=np.asarray(traj.t), transport_weights=np.asarray(traj.transport_weights),
            **({"tracer_v": np.asarray(traj.tracer_v)} if traj.tracer_v is not None else {}), tracer_u=np.asarray(traj.tracer_u),
            tracer_u_solved=np.asarray(traj.tracer_u_solved), roller_state=np.asarray(traj.roller_state),
            roller_velocity=np.asarray(traj.roller_velocity), roller_reaction=np.asarray(traj.roller_reaction),
            belt_mass=np.asarray(traj.belt_mass),
            tracer_x=mesh.tracer_x, tracer_z=mesh.tracer_z, roller_names=np.array(model.roller_names),
            roller_dofs=np.array(model.dofs), **({"u": np.asarray(traj.u)} if traj.u is not None else {}),
        )
        s["out"] = str(out)
    if args.plot:
        from .plot import plot_run

        times = None
        if getattr(args, "plot_times", None):
            try:
                times = [float(v) for v in args.plot_times.split(",")]
            except ValueError:
                raise UsageError(f"--plot-times = {args.plot_times!r}: expected comma-separated times in s") from None
        plot_run(traj, mesh, args.plot, times=times, title=f"{scene.name}: tracer trajectories")
        s["plot"] = str(args.plot)
    if args.json:
        print(json.dumps(s, indent=2))
    else:
        print(f"{'demo: ' if demo else ''}simulated {scene.name} ({scene.kind}, N = {model.n_unknowns}) for "
              f"{s['t_end_s']:g} s in {s['n_steps']} steps with the {model.integrator} integrator: "
              f"{wall:.2f} s run + {compile_s:.2f} s compile")
        print(f"  max |tracer u| = {s['tracer_u_max_abs_mm']:.6g} mm; roller surface speeds "
              + ", ".join(f"{k}: {v:.6g} m/s" for k, v in s["roller_speed_m_s"].items()))
        print(f"  belt mass {s['belt_mass_kg']:.9g} kg, max relative drift {s['belt_mass_rel_drift']:.2e}")
    lo, hi = s["transport_weight_range"]
    if lo < 0 or hi >= 1:
        print(f"jaxbelt: warning: the {model.transport!r} transport step extrapolated (weights in [{lo:.3g}, {hi:.3g}], "
              "outside [0, 1)); the results are not reliable. Use a smaller dt or --transport shift.", file=sys.stderr)
        for k in ("out", "plot"):
            if k in s:
                print(f"  wrote {s[k]}")
    return 0


def cmd_demo(args):
    args.scene = DEFAULT_SCENE
    args.t_end = args.dt = args.integrator = None
    args.out = args.out or "jaxbelt-demo.npz"
    args.plot = args.plot or "jaxbelt-demo.png"
    return cmd_simulate(args, demo=True)


def cmd_scenes(args):
    from .scene import builtin_scene_names, load_scene

    for name in builtin_scene_names():
        sc = load_scene(name)
        print(f"{name:32s} {sc.kind}  {sc.description}")
    return 0


def cmd_info(args):
    from .mesh import build_mesh
    from .model import compile_scene

    scene = _load(args.scene)
    mesh = build_mesh(scene)
    info = model_info(scene, mesh, compile_scene(scene, mesh))
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        _print_info(info)
    return 0


def cmd_plot_scene(args):
    from .mesh import build_mesh
    from .plot import plot_scene

    scene = _load(args.scene)
    out = args.out or f"{scene.name}-scene.png"
    plot_scene(scene, build_mesh(scene), out)
    print(f"wrote {out}")
    return 0


def build_parser():
    p = argparse.ArgumentParser(prog="jaxbelt", description="Differentiable conveyor-belt simulator (JAX)")
    sub = p.add_subparsers(dest="cmd", required=True)
    d = sub.add_parser("demo", help=f"simulate the built-in default scene ({DEFAULT_SCENE}), write .npz and .png")
    d.add_argument("--out", default=None)
    d.add_argument("--plot", default=None)
    d.add_argument("--json", action="store_true")
    sub.add_parser("scenes", help="list the built-in scenes")
    i = sub.add_parser("info", help="what the compiled model of a scene contains")
    i.add_argument("scene", help="TOML path or built-in scene name")
    i.add_argument("--json", action="store_true")
    ps = sub.add_parser("plot-scene", help="draw rollers, belt path, contact and tracer points")
    ps.add_argument("scene", help="TOML path or built-in scene name")
    ps.add_argument("--out", default=None, help="PNG path (default SCENE-scene.png)")
    s = sub.add_parser("simulate", help="run a scene")
    s.add_argument("scene", help="TOML path or built-in scene name")
    s.add_argument("--t-end", type=float, default=None, help="end time, s")
    s.add_argument("--dt", type=float, default=None, help="time step, s (checked against CFL)")
    s.add_argument("--integrator", choices=("naive", "direct", "eliminated"), default=None)
    s.add_argument("--solver", choices=("structured", "dense", "reuse"), default=None,
                   help="linear solver of the direct integrator (reuse: frozen factorisation + refinement)")
    s.add_argument("--transport", choices=("source", "shift"), default=None,
                   help="relabelling rule of the transport step (see jaxbelt.transport)")
    s.add_argument("--out", default=None, help="write the trajectory to this .npz")
    s.add_argument("--plot", default=None, help="write tracer/profile plots to this .png")
    s.add_argument("--plot-times", default=None, help="times (s, comma-separated) of the profiles along the belt")
    s.add_argument("--json", action="store_true", help="print a JSON summary")
    s.add_argument("--progress", action="store_true", help="progress bar even when not on a terminal")
    return p


def main(argv=None) -> int:
    from .scene import SceneError

    args = build_parser().parse_args(argv)
    try:
        return {"demo": cmd_demo, "scenes": cmd_scenes, "info": cmd_info, "simulate": cmd_simulate,
                "plot-scene": cmd_plot_scene}[args.cmd](args)
    except (SceneError, UsageError) as e:
        print(f"jaxbelt: error: {e}", file=sys.stderr)
        return 2
    except SimulationError as e:
        print(f"jaxbelt: error: {e}", file=sys.stderr)
        return 3


if __name__ == "__main__":
    sys.exit(main())
