"""Command line: ``jaxbelt demo | scenes | info | simulate | plot-scene | reduce``.

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


REDUCE_METHODS = ("pod", "dmd", "dmdc", "pdmd")
DEFAULT_MODES = {"pod": 20, "dmd": None, "dmdc": 30, "pdmd": 30}
DMD_STABLE_TOL = 1e-4  # |λ| ≤ 1 + tol kept: the static offset sits on a mode at λ ≈ 1 (± round-off)
REDUCE_HELP = """\
Train a reduced model and compare its tracer displacements with the full model's.

methods:
  pod   fully reduced POD step (solve and transport projected; jaxbelt.rom.fit_reduced_pod),
        trained on the first --train-steps steps of SCENE, or of the --train scenes (several
        configurations: the basis is linearised at the first one and run with SCENE's
        parameters); predicts all --steps steps from SCENE's initial state.
  dmd   exact DMD of SCENE's own pre-transport snapshots (one configuration): trains on the
        first --train-steps steps, predicts the rest from the last training snapshot; modes
        with |λ| > 1 + 1e-4 are discarded (the static offset lives on a mode at λ ≈ 1).
  dmdc  DMD with control (inputs: the configuration parameters), trained on the --train scenes.
  pdmd  parametric DMD (one DMD per --train scene, interpolated in parameter space).

dmdc and pdmd predict a configuration they have not seen: --train needs at least two scenes,
the nominal configuration plus one run per varied parameter, e.g. for a two-roller-1d-* scene
  --train two-roller-1d two-roller-1d-train1
(dmdc is valid at the drive speed(s) it was trained at; vary drive speeds with pdmd).

The error is the tracer RMSE in mm over the predicted steps (the source's tolerance: 0.02 mm);
the indicator (--stride K > 0) is the residual-based estimate of jaxbelt.rom.indicator. Times:
the full run is timed after compilation, offline = snapshot runs + fit (compilation included),
online = the reduced prediction after compilation; total speedup = full run / (offline +
online) (the source's eq. 7.5 with one test configuration).
"""


def _positive(name, v, low=1):
    if v is not None and v < low:
        raise UsageError(f"{name} = {v}: must be at least {low}")


def _timed(f, *args, repeat: int = 5, budget_s: float = 0.5):
    """``(result, seconds)`` of ``f(*args)`` with its outputs ready, after one untimed warm-up
    call (compilation): the fastest of up to ``repeat`` calls, fewer once ``budget_s`` is spent
    (so a long run is timed once; short ones are not at the mercy of one scheduler hiccup)."""
    import time

    import jax

    jax.block_until_ready(f(*args))
    times = []
    while len(times) < repeat and sum(times) < budget_s:
        t0 = time.perf_counter()
        out = jax.block_until_ready(f(*args))
        times.append(time.perf_counter() - t0)
    return out, min(times)


def _finite(v):
    v = float(v)
    return v if np.isfinite(v) else None


def _print_reduce(r):
    rows = [
        ("scene", r["scene"]), ("method", r["method"]),
        ("trained on", ", ".join(r["train"]) + f" ({r['train_steps']} steps each)"),
        ("modes", str(r["modes"])
         + (f" ({r['modes_discarded']} unstable discarded)" if r.get("modes_discarded") else "")),
        ("predicted", f"{r['predict_steps']} steps from step {r['predict_from_step']} ({r['compared']})"),
        ("RMSE", _fmt(r["rmse_mm"], " mm")), ("RRMSE", _fmt(r["rrmse"])),
        ("max RMSE over time", _fmt(r["max_rmse_over_time_mm"], " mm")),
        ("error estimate", _fmt(r["error_estimate_mm"], " mm") if r["error_estimate_mm"] is not None
         else "-" if r["stride"] == 0 else "nan"),
    ]
    tm = r["timings"]
    rows += [("full run", f"{tm['full_run_s']:.4g} s"), ("offline", f"{tm['offline_s']:.4g} s (snapshots + fit)"),
             ("online", f"{tm['online_s']:.4g} s"), ("speedup online", _fmt(tm["speedup_online"], "×")),
             ("speedup total", _fmt(tm["speedup_total"], "×"))]
    if "plot" in r:
        rows.append(("plot", r["plot"]))
    w = max(len(k) for k, _ in rows)
    for k, v in rows:
        print(f"  {k:<{w}}  {v}")


def _fmt(v, unit=""):
    return "nan" if v is None else f"{v:.4g}{unit}"


def cmd_reduce(args):
    import jax
    import jax.numpy as jnp

    from . import initial_state, simulate
    from . import rom
    from .model import compile_scene
    from .rom.indicator import residual_indicator

    method = args.method
    _positive("--modes", args.modes)
    _positive("--steps", args.steps)
    _positive("--train-steps", args.train_steps, 2 if method == "dmd" else 1)
    _positive("--stride", args.stride, 0)
    train_names = list(args.train or [])
    if method in ("dmdc", "pdmd") and len(train_names) < 2:
        raise UsageError(f"--method {method} needs --train with at least two scenes (the nominal configuration plus "
                         f"one run per varied parameter), e.g. --train two-roller-1d two-roller-1d-train1")
    if method == "dmd" and any(t != args.scene for t in train_names):
        raise UsageError("--method dmd fits one configuration, the scene's own first --train-steps steps; "
                         "use dmdc or pdmd (or pod) to train on other scenes")

    if args.plot and not Path(args.plot).resolve().parent.is_dir():
        raise UsageError(f"--plot {args.plot}: the folder {Path(args.plot).parent} does not exist")
    scene = _load(args.scene)
    test = compile_scene(scene)
    train_names = train_names or [args.scene]
    train_models = [test if t == args.scene else compile_scene(_load(t)) for t in train_names]
    for name, m in zip(train_names, train_models):
        if m.n_unknowns != test.n_unknowns or m.kind != test.kind or m.n_tracers != test.n_tracers:
            raise UsageError(f"--train {name}: {m.kind} model with N = {m.n_unknowns} and {m.n_tracers} tracers; "
                             f"{scene.name} has {test.kind}, N = {test.n_unknowns}, {test.n_tracers} tracers "
                             "(training scenes need the same mesh)")
        if m.dt != test.dt:
            raise UsageError(f"--train {name}: dt = {m.dt:g} s, {scene.name} has dt = {test.dt:g} s")
    if method == "pod":
        for name, m in zip(train_names, train_models):
            if m.transport != "shift":
                raise UsageError(f"--method pod needs the 'shift' transport rule; {name} uses {m.transport!r}")
    n = int(args.steps or test.n_steps)
    m_train = int(args.train_steps or min(200, n // 2))
    if m_train < (2 if method == "dmd" else 1):
        raise UsageError(f"--steps = {n}: too few steps to train on (--train-steps = {m_train})")
    if method == "dmd" and m_train >= n:
        raise UsageError(f"--train-steps = {m_train} with --steps = {n}: dmd predicts the steps after the "
                         "training window, so --train-steps must be smaller than --steps")
    modes = DEFAULT_MODES[method] if args.modes is None else args.modes

    # the full model, timed after its compilation
    (_, traj), full_s = _timed(lambda: simulate(test, n_steps=n), repeat=3, budget_s=1.0)
    if not np.all(np.isfinite(np.asarray(traj.tracer_u))):
        raise SimulationError(f"the full simulation of {scene.name} diverged; nothing to compare with")
    steps_full = np.rint(np.asarray(traj.t) / test.dt).astype(int)  # step number of each output row
    C = rom.tracer_operator(test)
    Cz = jnp.concatenate([C, jnp.zeros_like(C)], axis=1)
    z0 = rom.state_to_z(test, initial_state(test))
    mu = rom.parameters(test)

    import time

    t0 = time.perf_counter()
    extra = {}
    if method == "pod":
        snaps = []
        for m in train_models:
            _, Zpre, Zpost = rom.collect_first_order(m, m_train)
            snaps += [Zpre, Zpost]
        fit = rom.fit_reduced_pod(train_models[0], jnp.concatenate(snaps, axis=1), n_modes=modes)
        jax.block_until_ready(fit)
        offline_s = time.perf_counter() - t0
        xi0 = fit.project(test, initial_state(test))
        run = jax.jit(lambda f, x, p: f.run(x, p, n))
        out, online_s = _timed(run, fit, xi0, mu)
        pred, start, compared = out["tracer_u"], 0, "tracer_u"
        states = (lambda: fit.fields(jnp.concatenate([xi0[None], out["xi"]])), "post")
        modes_used = fit.n_modes

        def plot_data():
            return dict(singular_values=fit.singular_values)
    elif method == "dmd":
        _, Zpre, _ = rom.collect_first_order(test, m_train)
        full_fit = rom.fit_dmd(Zpre, rank=modes)
        fit = full_fit.stable(DMD_STABLE_TOL)
        jax.block_until_ready(fit)
        offline_s = time.perf_counter() - t0
        x_start, k = Zpre[:, -1], n - m_train
        pred_f = jax.jit(lambda f, x: f.predict(x, k, observe=Cz))
        pred, online_s = _timed(pred_f, fit, x_start)
        start, compared = m_train, "tracer_u_solved"
        states = (lambda: jnp.concatenate([x_start[None], fit.predict(x_start, k)]), "pre")
        modes_used = int(fit.eigs.shape[0])
        extra["modes_discarded"] = int(full_fit.eigs.shape[0] - modes_used)

        def plot_data():
            return dict(singular_values=jnp.linalg.svd(Zpre[:, :-1], compute_uv=False),
                        marked=int(full_fit.eigs.shape[0]), eigs=fit.eigs, eig_weights=fit.scaled_mode_norms(x_start))
    else:
        trajs = [rom.collect_first_order(m, m_train)[2] for m in train_models]
        params = [rom.parameters(m) for m in train_models]
        if method == "dmdc":
            X, Y, U = rom.stack_controlled(trajs, [rom.belt_inputs(p, Z.shape[1] - 1) for p, Z in zip(params, trajs)])
            fit = rom.fit_dmdc(X, Y, U, rank=modes)
            jax.block_until_ready(fit)
            offline_s = time.perf_counter() - t0
            u = rom.belt_inputs(mu, 1)[:, 0]
            pred_f = jax.jit(lambda f, z, u: f.predict(z, u, n, observe=Cz))
            pred, online_s = _timed(pred_f, fit, z0, u)
            states = (lambda: jnp.concatenate([z0[None], fit.predict(z0, u, n)]), "post")
            modes_used = int(fit.A.shape[0])

            def plot_data():
                lam, W = np.linalg.eig(np.asarray(fit.A))
                b = np.linalg.solve(W, np.asarray(fit.basis.T @ z0))  # amplitudes of the start state
                return dict(singular_values=jnp.linalg.svd(jnp.concatenate([X, Y], axis=1), compute_uv=False),
                            eigs=lam, eig_weights=np.abs(b) * np.linalg.norm(W, axis=0))
        else:
            fit = rom.fit_parametric_dmd(trajs, jnp.stack(params), rank=modes)
            jax.block_until_ready(fit)
            offline_s = time.perf_counter() - t0
            pred_f = jax.jit(lambda f, p: f.predict(p, n + 1, observe=Cz)[1:])
            pred, online_s = _timed(pred_f, fit, mu)
            states = (lambda: fit.predict(mu, n + 1), "post")
            modes_used = int(fit.basis.shape[1])

            def plot_data():
                w = (np.abs(np.asarray(fit.amplitudes)) * np.linalg.norm(np.asarray(fit.modes), axis=1)).reshape(-1)
                keep = w > 0  # not the padding of the per-configuration DMDs
                return dict(singular_values=jnp.linalg.svd(jnp.concatenate(trajs, axis=1), compute_uv=False),
                            eigs=np.asarray(fit.eigs).reshape(-1)[keep], eig_weights=w[keep])
        start, compared = 0, "tracer_u"

    # compare at the full run's output steps inside the predicted window (start, n]
    rows = np.flatnonzero((steps_full > start) & (steps_full <= n))
    truth = np.asarray(getattr(traj, compared))[rows]
    pred = np.asarray(pred)[steps_full[rows] - start - 1]
    err_t = np.sqrt(np.mean((truth - pred) ** 2, axis=1)) * 1e3
    estimate = None
    if args.stride > 0:
        S, order = states
        estimate = residual_indicator(test, S(), stride=args.stride, order=order)
    online = max(online_s, 1e-12)
    report = dict(
        scene=scene.name, method=method, train=train_names, modes=modes_used, **extra, train_steps=m_train,
        steps=n, predict_from_step=start, predict_steps=n - start, compared=compared,
        n_unknowns=test.n_unknowns, n_tracers=test.n_tracers,
        rmse_mm=_finite(rom.rmse(truth, pred) * 1e3), rrmse=_finite(rom.rrmse(truth, pred)),
        max_rmse_over_time_mm=_finite(np.max(err_t)) if err_t.size else None,
        error_estimate_mm=_finite(estimate["estimate_mm"][-1]) if estimate is not None else None,
        stride=args.stride, n_test_configs=1,
        timings=dict(full_run_s=full_s, offline_s=offline_s, online_s=online_s,
                     speedup_online=full_s / online, speedup_total=1 * full_s / (offline_s + online_s)),
    )
    if args.plot:
        from .plot import plot_reduction

        pd = plot_data()
        est = {} if estimate is None else dict(  # the estimate after step k is that of state k + 1
            estimate_t=(start + np.asarray(estimate["step"]) + 1) * test.dt,
            estimate_mm=np.asarray(estimate["estimate_mm"]))
        plot_reduction(dict(report, modes=pd.pop("marked", modes_used)), steps_full[rows] * test.dt, err_t, args.plot,
                       singular_values=np.asarray(pd.pop("singular_values")), **pd, **est)
        report["plot"] = str(args.plot)
    if args.json:
        print(json.dumps(report, indent=2))
    else:
        print(f"reduced {scene.name} ({scene.kind}, N = {test.n_unknowns}) with {method}:")
        _print_reduce(report)
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
    r = sub.add_parser("reduce", help="train a reduced model (pod, dmd, dmdc, pdmd): accuracy and speedup vs the full one",
                       description=REDUCE_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    r.add_argument("scene", help="TOML path or built-in scene name: the configuration to predict")
    r.add_argument("--method", choices=REDUCE_METHODS, required=True)
    r.add_argument("--train", nargs="+", default=None, metavar="SCENE",
                   help="training scenes (pod: default SCENE itself; dmdc/pdmd: required, at least two: the nominal "
                        "configuration plus one run per varied parameter)")
    r.add_argument("--modes", type=int, default=None, metavar="N",
                   help="reduced dimension (default: pod 20, dmdc/pdmd 30, dmd all non-negligible)")
    r.add_argument("--train-steps", type=int, default=None, metavar="N", help="full-order steps per training scene "
                   "(default min(200, steps/2))")
    r.add_argument("--steps", type=int, default=None, metavar="N",
                   help="steps to predict and compare (default: the scene's t_end / dt)")
    r.add_argument("--stride", type=int, default=10, metavar="K",
                   help="residual indicator every K-th step (0: skip; default 10)")
    r.add_argument("--plot", default=None, metavar="FILE.png",
                   help="write singular values / eigenvalues / error over time to this .png")
    r.add_argument("--json", action="store_true", help="print a JSON summary")
    return p


def main(argv=None) -> int:
    from .scene import SceneError

    args = build_parser().parse_args(argv)
    try:
        return {"demo": cmd_demo, "scenes": cmd_scenes, "info": cmd_info, "simulate": cmd_simulate,
                "plot-scene": cmd_plot_scene, "reduce": cmd_reduce}[args.cmd](args)
    except (SceneError, UsageError) as e:
        print(f"jaxbelt: error: {e}", file=sys.stderr)
        return 2
    except SimulationError as e:
        print(f"jaxbelt: error: {e}", file=sys.stderr)
        return 3


if __name__ == "__main__":
    sys.exit(main())
