"""``jaxbelt simulate``: run a scene (``jaxbelt demo`` runs it on the default scene)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ._common import SCENE_HELP, SimulationError, UsageError, _emit, _load


def add_parser(subparsers):
    s = subparsers.add_parser("simulate", help="run a scene")
    s.add_argument("scene", help=SCENE_HELP)
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
    s.add_argument("--plot-fields", default=None, metavar="FILE.png",
                   help="heat maps of the displacement fields over the unrolled belt at --field-times "
                        "(full fields are recorded at those times only)")
    s.add_argument("--field-times", default=None, metavar="T1,T2,...",
                   help="times (s, comma-separated) of --plot-fields / --plot-3d (default: three evenly spaced, "
                        "the last one included; --plot-3d draws the last)")
    s.add_argument("--field-components", default=None, metavar="u,v",
                   help="components of --plot-fields (default: u,v in 2D, u in 1D)")
    s.add_argument("--plot-3d", default=None, metavar="FILE.png",
                   help="3D view of the rollers and the belt coloured by its displacement magnitude, at the last "
                        "field time")
    s.add_argument("--exaggerate", type=float, default=1.0, metavar="F",
                   help="--plot-3d: draw displacements and roller motions F times their size (default 1)")
    s.add_argument("--json", action="store_true", help="print a JSON summary")
    s.add_argument("--progress", action="store_true", help="progress bar even when not on a terminal")
    s.set_defaults(func=run)
    return s


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
        belt_off_roller=belt_off_roller(model, traj),
    )


def _plot_fields(args, scene, mesh, model, traj, request, fields, s):
    """The figures of ``--plot-fields`` (heat maps) and ``--plot-3d`` (the last field time)."""
    from types import SimpleNamespace

    from .. import plot

    if getattr(args, "plot_fields", None):
        axes = plot.plot_fields(model, SimpleNamespace(t=request["t"], u=fields), times=list(request["t"]),
                                components=request["components"], title=scene.name)
        fig = axes[0, 0].figure
        fig.savefig(args.plot_fields, dpi=120)
        plot._plt().close(fig)
        s["plot_fields"] = str(args.plot_fields)
    if getattr(args, "plot_3d", None):
        row = request["rows"][-1]
        chi = np.asarray(traj.roller_state)[row]
        ax = plot.plot_belt_3d(model, fields[-1], chi=chi, mesh=mesh, exaggerate=request["exaggerate"],
                               title=f"{scene.name} at t = {request['t'][-1]:.4g} s")
        ax.figure.savefig(args.plot_3d, dpi=120)
        plot._plt().close(ax.figure)
        s["plot_3d"] = str(args.plot_3d)


def belt_off_roller(model, traj):
    """The first recorded step at which a belt edge has left a roller's face (``edge_margin`` < 0):
    ``{"roller", "step", "t_s", "margin_mm"}``, or ``None`` (and always in 1D)."""
    if traj.edge_margin is None:
        return None
    m = np.asarray(traj.edge_margin)
    bad = np.argwhere(m < 0)
    if not len(bad):
        return None
    k, j = bad[0]
    t = float(np.asarray(traj.t)[k])
    return {"roller": model.roller_names[j], "step": int(round(t / model.dt)), "t_s": t, "margin_mm": float(m[k, j] * 1e3)}


def _field_request(args, scene):
    """The recorded rows, their times and the components of ``--plot-fields`` / ``--plot-3d``
    (checked before anything is compiled), or ``None`` when neither is asked for."""
    plot_fields, plot_3d = getattr(args, "plot_fields", None), getattr(args, "plot_3d", None)
    times_arg, comps_arg = getattr(args, "field_times", None), getattr(args, "field_components", None)
    if not (plot_fields or plot_3d):
        for key, v in (("--field-times", times_arg), ("--field-components", comps_arg)):
            if v is not None:
                raise UsageError(f"{key} = {v!r}: needs --plot-fields or --plot-3d")
        return None
    ex = getattr(args, "exaggerate", 1.0)
    if not np.isfinite(ex) or ex < 0:
        raise UsageError(f"--exaggerate = {ex}: must be a finite number >= 0")
    comps = None
    if comps_arg is not None:
        comps = tuple(c.strip() for c in comps_arg.split(",") if c.strip())
        bad = [c for c in comps if c not in ("u", "v")]
        if bad or not comps:
            raise UsageError(f"--field-components = {comps_arg!r}: expected u, v or u,v")
        if "v" in comps and scene.kind == "1d":
            raise UsageError(f"--field-components = {comps_arg!r}: the 1D scene {scene.name!r} has no lateral "
                             "displacement v (only u)")
    every, dt = scene.output.every, scene.time.dt
    n_out = scene.time.n_steps // every
    if n_out < 1:
        raise UsageError(f"--plot-fields: the run records no step (t_end < {every} × dt)")
    t_rec = (np.arange(n_out) + 1) * every * dt
    times = None
    if times_arg is not None:
        try:
            times = [float(v) for v in times_arg.split(",")]
        except ValueError:
            raise UsageError(f"--field-times = {times_arg!r}: expected comma-separated times in s") from None
    from ..plot import select_times

    try:
        rows = select_times(t_rec, times, spacing=every * dt)
    except ValueError as e:
        raise UsageError(f"--field-times = {times_arg!r}: {str(e).removeprefix('times: ')}") from None
    return dict(rows=rows, t=t_rec[rows], components=comps, exaggerate=ex)


def _simulate_recording_fields(model, integrator, rows, progress, chunk=200):
    """:func:`jaxbelt.simulate_with_progress` with the full field ``u`` kept at the recorded rows
    ``rows`` only: the run goes in chunks of a model with ``full_fields=True`` and each chunk's
    fields are dropped but for those rows, so memory holds one chunk's fields, not the run's.

    **Returns:** ``(traj without u, fields (len(rows), n_xi, b), timing)``; ``rows`` in the order
    given (repeats allowed)."""
    import dataclasses
    import time

    import jax
    import jax.numpy as jnp
    from tqdm import tqdm

    from ..state import initial_state
    from ..timeloop import _run_jit

    model = model.replace(full_fields=True)
    n_steps, every = int(model.n_steps), model.every
    chunk = max(every, (chunk // every) * every)
    state = initial_state(model)
    sizes = [min(chunk, n_steps - k) for k in range(0, n_steps, chunk)]
    t0 = time.perf_counter()
    compiled = {k: _run_jit.lower(model, integrator, state, k).compile() for k in sorted(set(sizes))}
    compile_s = time.perf_counter() - t0
    wanted, kept, parts, row0 = set(rows), {}, [], 0
    t0 = time.perf_counter()
    with tqdm(total=n_steps, unit="step", disable=not progress, leave=False) as bar:
        for k in sizes:
            state, traj = compiled[k](model, integrator, state, k)
            n_rec = traj.t.shape[0]
            for r in wanted:
                if row0 <= r < row0 + n_rec:
                    kept[r] = np.asarray(traj.u[r - row0])
            parts.append(dataclasses.replace(traj, u=None))
            row0 += n_rec
            bar.update(k)
    jax.block_until_ready(state.u)
    run_s = time.perf_counter() - t0
    traj = jax.tree.map(lambda *xs: jnp.concatenate(xs, axis=0), *parts)
    return traj, np.stack([kept[r] for r in rows]), {"compile_s": compile_s, "run_s": run_s}


def run(args, demo=False):
    from .. import compile_scene, simulate_with_progress
    from ..timeloop import NonFiniteStateError, check_finite
    from ..integrators import make_integrator
    from ..mesh import build_mesh

    scene = _load(args.scene, args.t_end, args.dt, args.integrator, getattr(args, "transport", None),
                  getattr(args, "solver", None))
    request = _field_request(args, scene)  # checked before anything is compiled
    mesh = build_mesh(scene)
    model = compile_scene(scene, mesh)
    integrator = make_integrator(model.integrator, model)
    from ..prestress import slack_message, slack_spans

    slack = slack_spans(scene, mesh, model)
    if slack:  # before the run: the user learns it even if the run is long
        print(f"jaxbelt: warning: {slack_message(slack)}; the linear model carries compression like "
              "tension, so the results are not a real belt's", file=sys.stderr)
    progress = getattr(args, "progress", False) or (not args.json and sys.stderr.isatty())
    fields = None
    if request is None or model.full_fields:
        _, traj, timing = simulate_with_progress(model, integrator, progress=progress, check=False)
        if request is not None:
            fields = np.asarray(traj.u)[request["rows"]]
    else:  # full fields recorded at the requested times only
        traj, fields, timing = _simulate_recording_fields(model, integrator, request["rows"], progress)
    wall, compile_s = timing["run_s"], timing["compile_s"]
    s = _summary(scene, model, traj, wall, compile_s)
    s["slack"] = slack
    try:
        check_finite(traj, model.dt)
    except NonFiniteStateError as e:
        raise SimulationError(f"{e} (transport weights {s['transport_weight_range']})") from None
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
            **({"field_t": request["t"], "field_u": fields} if fields is not None else {}),
        )
        s["out"] = str(out)
    if args.plot:
        from ..plot import plot_run

        times = None
        if getattr(args, "plot_times", None):
            try:
                times = [float(v) for v in args.plot_times.split(",")]
            except ValueError:
                raise UsageError(f"--plot-times = {args.plot_times!r}: expected comma-separated times in s") from None
        try:
            plot_run(traj, mesh, args.plot, times=times, title=f"{scene.name}: tracer trajectories")
        except ValueError as e:
            raise UsageError(f"--plot-times = {args.plot_times!r}: {str(e).removeprefix('times: ')}") from None
        s["plot"] = str(args.plot)
    if request is not None:
        s["field_times_s"] = [float(v) for v in request["t"]]
        _plot_fields(args, scene, mesh, model, traj, request, fields, s)

    def print_text(s):
        print(f"{'demo: ' if demo else ''}simulated {scene.name} ({scene.kind}, N = {model.n_unknowns}) for "
              f"{s['t_end_s']:g} s in {s['n_steps']} steps with the {model.integrator} integrator: "
              f"{wall:.2f} s run + {compile_s:.2f} s compile")
        print(f"  max |tracer u| = {s['tracer_u_max_abs_mm']:.6g} mm; roller surface speeds "
              + ", ".join(f"{k}: {v:.6g} m/s" for k, v in s["roller_speed_m_s"].items()))
        print(f"  belt mass {s['belt_mass_kg']:.9g} kg, max relative drift {s['belt_mass_rel_drift']:.2e}")

    _emit(args, s, print_text)
    off = s["belt_off_roller"]
    if off:
        print(f"jaxbelt: warning: the belt runs off {off['roller']!r} at step {off['step']} (t = {off['t_s']:g} s): "
              f"its edge is {-off['margin_mm']:.3g} mm beyond the roller's face; later results are not physical",
              file=sys.stderr)
    lo, hi = s["transport_weight_range"]
    if lo < 0 or hi >= 1:
        advice = "a smaller dt" + (" or --transport shift" if model.transport != "shift" else "")
        print(f"jaxbelt: warning: the {model.transport!r} transport step extrapolated (weights in [{lo:.3g}, {hi:.3g}], "
              f"outside [0, 1)); the results are not reliable. Use {advice}.", file=sys.stderr)
    if not args.json:
        for k in ("out", "plot", "plot_fields", "plot_3d"):
            if k in s:
                print(f"  wrote {s[k]}")
    return 0
