"""``jaxbelt info``: what the compiled model of a scene contains."""

from __future__ import annotations

import jax
import numpy as np

from ..accuracy import one_d_counterpart
from ..assembly import dae_matrices
from ..timeloop import RunOptions
from ._common import SCENE_HELP, emit, load_run


def add_parser(subparsers):
    p = subparsers.add_parser("info", help="what the compiled model of a scene contains")
    p.add_argument("scene", help=SCENE_HELP)
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)
    return p


def run(args):
    scene, mesh, model, options = load_run(args.scene)
    emit(args, model_info(scene, mesh, model, options), _print_info)
    return 0


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


# the assembly as one compiled program, not op by op (~0.1 s instead of ~0.8 s on a small scene)
_compiled_dae_matrices = jax.jit(dae_matrices)


def model_info(scene, mesh, model, options: RunOptions | None = None) -> dict:
    """What the model of a scene contains and how the scene runs it (``jaxbelt info``): the run
    settings come from ``options`` (default :meth:`jaxbelt.RunOptions.from_scene`), the solver's
    names from the scene's ``[solver]``."""
    options = RunOptions.from_scene(scene) if options is None else options
    K, _ = _compiled_dae_matrices(model, model.m_e0)
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
        dt_s=options.dt, t_end_s=scene.time.t_end, n_steps=options.n_steps,
        cfl=float(max((r.speed for r in scene.rollers if r.role == "drive"), default=0) * options.dt / mesh.ell.min()),
        integrator=scene.solver.integrator, linear_solver=scene.solver.linear_solver,
        transport=options.solver.transport,
        n_tracers=model.n_tracers, output_every=options.saveat.every, full_fields=options.saveat.fields,
        pretension_strain=float(mesh.length / (scene.belt.length or mesh.length) - 1.0),
        dynamic_roller_rows=int(np.sum(dyn)), rollers=rollers, segments=segments,
        control=[loop_info(c, options.dt) for c in scene.control],
        lateral_transport=scene.solver.lateral_transport,
        automatic=automatic_choices(scene, mesh),
    )


def loop_info(c, dt: float) -> dict:
    """One steering loop of a scene (``[[control]]``) in the units of its table: the actuator and
    axis, the sensor, the gains, the sample period (default: every step), range, rate limit, lag,
    set point, noise and edge profile."""
    return dict(actuator=c.actuator, axis=c.axis, sensor_mm=[c.sensor[0] * 1e3, c.sensor[1] * 1e3],
                kp_mrad_per_mm=c.kp, ki_mrad_per_mm_s=c.ki, kd_mrad_s_per_mm=c.kd,
                sample_s=c.sample if c.sample is not None else dt, limit_mrad=c.limit * 1e3,
                rate_limit_mrad_s=None if c.rate_limit is None else c.rate_limit * 1e3, lag_s=c.lag,
                setpoint_mm=c.setpoint * 1e3, noise_um=c.noise * 1e6,
                edge_profile_um=[[h, a * 1e6, ph] for h, a, ph in c.edge_profile])


def automatic_choices(scene, mesh) -> list[str]:
    """What the program decides for this scene itself, in words (``jaxbelt info``)."""
    pre = mesh.length / (scene.belt.length or mesh.length) - 1.0
    tension = pre > 0 or any(r.role == "tension" for r in scene.rollers)
    acc = scene.solver.accuracy_um
    out = [f"grid: chosen for {acc:g} µm when the scene runs (the cheapest n_xi, n_eta, dt whose estimated "
           "discretisation error meets it, verified by its own estimate)" if acc is not None else
           "grid: the scene's own (--accuracy-um or [solver] accuracy_um chooses one for an accuracy)",
           "precision: float64 (with an accuracy asked, simulate runs float32 where its rounding, measured on the "
           "chosen grid, fits within the accuracy and the run is faster; the design commands keep float64)"]
    if scene.kind == "2d":
        s1, why = one_d_counterpart(scene)
        out.append("model: 2D" + (f"; with an accuracy asked, simulate runs the 1D counterpart where the models' "
                                  f"measured difference fits ({why})" if s1 is not None else f" ({why})"))
    if scene.solver.linear_solver == "reuse":
        exact = scene.solver.transport == "shift" and not scene.solver.lateral_transport
        out.append("reuse solver: " + ("no refinement (shift transport, no lateral transport: the first step's "
                                       "factors solve every step exactly)" if exact else
                                       "2 refinement iterations a step (the step matrix drifts)"))
    if scene.kind == "2d":
        st = scene.solver.tension_stiffening
        out.append("tension stiffening: " + ("off" if not st else "on, acting (tension in the belt)" if tension else
                                             "on, idle here (no pre-tension and no tension roller: nothing to stiffen)"))
    return out


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
    for c in info["control"]:
        rate = "no rate limit" if c["rate_limit_mrad_s"] is None else f"rate ≤ {c['rate_limit_mrad_s']:g} mrad/s"
        kd = f", kd {c['kd_mrad_s_per_mm']:g} mrad·s/mm" if c["kd_mrad_s_per_mm"] else ""
        print(f"  steering loop: {c['actuator']!r} tilted about {c['axis']}, edge sensor at s = {c['sensor_mm'][0]:g} mm, "
              f"z = {c['sensor_mm'][1]:g} mm, sampled every {c['sample_s']:g} s; PI gains kp {c['kp_mrad_per_mm']:g} "
              f"mrad/mm, ki {c['ki_mrad_per_mm_s']:g} mrad/(mm s){kd}; range ±{c['limit_mrad']:g} mrad, {rate}, "
              f"lag {c['lag_s']:g} s; sensor noise {c['noise_um']:g} µm, edge profile "
              + (", ".join(f"{a:g} µm × {h:g}/turn" for h, a, _ in c["edge_profile_um"]) or "none"))
    for line in info["automatic"]:
        print(f"  automatic: {line}")
    for s in info["segments"]:
        print(f"    {s['kind']:6s} {s['name']:24s} {s['length_mm']:10.3f} mm  {s['elements']:4d} elements")
