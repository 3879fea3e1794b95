"""``jaxbelt simulate``: run a scene (``jaxbelt demo`` runs it on the default scene)."""

from __future__ import annotations

import dataclasses
import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from .. import plot
from ..accuracy import precision_scope
from ..control import loop_summary
from ..prestress import overstrain_message, overstrained_spans, slack_message, slack_spans, span_forces
from ..registry import INTEGRATORS, LINEAR_SOLVERS, START_RULES, TRANSPORT_RULES
from ..state import SWING_WARN_FRACTION, initial_state, start_swing
from ..run_checks import NonFiniteStateError, check_finite
from ..timeloop import simulate_in_chunks
from ._accuracy import add_accuracy_arguments, choose_accuracy, error_estimate, print_accuracy
from ._common import SCENE_HELP, SimulationError, UsageError, emit, load_run, output_file, rebuild


def add_parser(subparsers):
    s = subparsers.add_parser("simulate", help="run a scene")
    s.add_argument("scene", help=SCENE_HELP)
    s.add_argument("--t-end", type=float, default=None, help="end time, s")
    s.add_argument("--from", dest="accuracy_from", type=float, default=0.0, metavar="S",
                   help="with --accuracy-um or --error-estimate: the error over the output times from S s on, "
                        "leaving out the start-up transient, which converges slowest (default 0: the whole run)")
    s.add_argument("--start", choices=tuple(START_RULES), default=None,
                   help="rest: belt and idle rollers at rest, the drive at speed (an impulsive start, model "
                        "specification); running: everything at the drive speed already (no start-up swing); "
                        "default: the scene's [time] start, else rest")
    s.add_argument("--dt", type=float, default=None, help="time step, s (checked against CFL)")
    s.add_argument("--integrator", choices=tuple(INTEGRATORS), default=None,
                   help="time integrator (default: the scene's, direct unless it names one)")
    s.add_argument("--solver", choices=tuple(LINEAR_SOLVERS), default=None,
                   help="linear solver of the direct integrator (default: the scene's, kept-interior unless it "
                        "names one; reuse: the first step's factors kept, refined every step)")
    s.add_argument("--transport", choices=tuple(TRANSPORT_RULES), default=None,
                   help="relabelling rule of the transport step (see jaxbelt.transport; default: the scene's)")
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
    add_accuracy_arguments(s)
    s.add_argument("--json", action="store_true", help="print a JSON summary")
    s.add_argument("--progress", action="store_true", help="progress bar even when not on a terminal")
    s.set_defaults(func=run)
    return s


def _start_swing(scene, mesh, options):
    """From rest, the idle rollers' start-up swing (:func:`jaxbelt.state.start_swing`); warned about
    before the run where the run's time steps leave more than :data:`SWING_WARN_FRACTION` of it."""
    if scene.time.start != "rest":
        return None
    swing = start_swing(scene, mesh, options.dt, options.n_steps)
    kept = [(n, f, left) for n, f, left in swing if left > SWING_WARN_FRACTION]
    if kept:
        name, f, left = max(kept, key=lambda r: r[2])
        print(f"jaxbelt: warning: from rest, {name}'s start-up swing (~{f:.0f} Hz) keeps {left:.1%} of its amplitude "
              f"at the end: the model has no damping and Backward Euler damps it little at dt = {options.dt:g} s, so "
              "the answer shows the start and differs from a run at a larger dt; --start running starts the "
              "machine running (docs/speed.md)", file=sys.stderr)
    return swing


def _summary(scene, options, model, traj, timing):
    t = np.asarray(traj.t)
    tu = np.asarray(traj.tracer_u)
    rv = np.asarray(traj.roller_velocity)
    mass = np.asarray(traj.belt_mass)
    tw = np.asarray(traj.transport_weights)
    az = model.dofs.index("az")
    return dict(
        scene=scene.name, integrator=scene.solver.integrator, n_steps=int(round(t[-1] / options.dt)),
        t_end_s=float(t[-1]), n_unknowns=model.n_unknowns, wall_s=timing["run_s"], compile_s=timing["compile_s"],
        tracer_u_max_abs_um=float(np.max(np.abs(tu)) * 1e6), tracer_u_final_um=(tu[-1] * 1e6).round(3).tolist(),
        tracer_v_max_abs_um=None if traj.tracer_v is None else float(np.max(np.abs(np.asarray(traj.tracer_v))) * 1e6),
        roller_speed_m_s={r.name: float(abs(rv[-1, j, az]) * r.radius) for j, r in enumerate(scene.rollers)},
        belt_mass_kg=float(mass[-1]), belt_mass_rel_drift=float(np.max(np.abs(mass - mass[0])) / mass[0]),
        transport=options.solver.transport,
        transport_weight_range=[float(np.min(tw[:, 0])), float(np.max(tw[:, 1]))],
        belt_off_roller=belt_off_roller(model, traj, options.dt),
        **({} if model.control is None else
           {"control": loop_summary(model.control, traj.control_u, traj.sensor_v, np.asarray(traj.t))}),
    )


def _plot_fields(args, scene, mesh, model, traj, request, fields, s):
    """The figures of ``--plot-fields`` (heat maps) and ``--plot-3d`` (the last field time)."""
    from matplotlib import pyplot

    if getattr(args, "plot_fields", None):
        axes = plot.plot_fields(model, SimpleNamespace(t=request["t"], u=fields), times=list(request["t"]),
                                components=request["components"], title=scene.name)
        fig = axes[0, 0].figure
        fig.savefig(args.plot_fields, dpi=120)
        pyplot.close(fig)
        s["plot_fields"] = str(args.plot_fields)
    if getattr(args, "plot_3d", None):
        row = request["rows"][-1]
        chi = np.asarray(traj.roller_state)[row]
        ax = plot.plot_belt_3d(model, fields[-1], chi=chi, mesh=mesh, exaggerate=request["exaggerate"],
                               title=f"{scene.name} at t = {request['t'][-1]:.4g} s")
        ax.figure.savefig(args.plot_3d, dpi=120)
        pyplot.close(ax.figure)
        s["plot_3d"] = str(args.plot_3d)


def belt_off_roller(model, traj, dt):
    """The first recorded step at which a belt edge has left a roller's face (``edge_margin`` < 0):
    ``{"roller", "step", "t_s", "margin_um"}``, or ``None`` (and always in 1D)."""
    if traj.edge_margin is None:
        return None
    m = np.asarray(traj.edge_margin)
    bad = np.argwhere(m < 0)
    if not len(bad):
        return None
    k, j = bad[0]
    t = float(np.asarray(traj.t)[k])
    return {"roller": model.roller_names[j], "step": int(round(t / float(dt))), "t_s": t, "margin_um": float(m[k, j] * 1e6)}


def _field_request(args, scene, options):
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
    every, dt = options.saveat.every, options.dt
    n_out = options.n_steps // every
    if n_out < 1:
        raise UsageError(f"--plot-fields: the run records no step (t_end < {every} × dt)")
    t_rec = (np.arange(n_out) + 1) * every * dt
    times = None
    if times_arg is not None:
        try:
            times = [float(v) for v in times_arg.split(",")]
        except ValueError:
            raise UsageError(f"--field-times = {times_arg!r}: expected comma-separated times in s") from None
    try:
        rows = plot.select_times(t_rec, times, spacing=every * dt)
    except ValueError as e:
        raise UsageError(f"--field-times = {times_arg!r}: {str(e).removeprefix('times: ')}") from None
    return dict(rows=rows, t=t_rec[rows], components=comps, exaggerate=ex)


def _write_npz(path, traj, mesh, model, request, fields):
    np.savez(
        Path(path), t=np.asarray(traj.t), transport_weights=np.asarray(traj.transport_weights),
        **({"tracer_v": np.asarray(traj.tracer_v)} if traj.tracer_v is not None else {}),
        tracer_u=np.asarray(traj.tracer_u), tracer_u_solved=np.asarray(traj.tracer_u_solved),
        roller_state=np.asarray(traj.roller_state), roller_velocity=np.asarray(traj.roller_velocity),
        roller_reaction=np.asarray(traj.roller_reaction), belt_mass=np.asarray(traj.belt_mass),
        tracer_x=mesh.tracer_x, tracer_z=mesh.tracer_z, roller_names=np.array(model.roller_names),
        roller_dofs=np.array(model.dofs), **({"u": np.asarray(traj.u)} if traj.u is not None else {}),
        **({"control_u": np.asarray(traj.control_u), "sensor_v": np.asarray(traj.sensor_v)}
           if traj.control_u is not None else {}),
        **({"field_t": request["t"], "field_u": fields} if fields is not None else {}),
    )


def _plot_tracers(args, scene, mesh, traj):
    """The figure of ``--plot`` (tracer trajectories, profiles at ``--plot-times``)."""
    times = None
    if getattr(args, "plot_times", None):
        try:
            times = [float(v) for v in args.plot_times.split(",")]
        except ValueError:
            raise UsageError(f"--plot-times = {args.plot_times!r}: expected comma-separated times in s") from None
    try:
        plot.plot_run(traj, mesh, args.plot, times=times, title=f"{scene.name}: tracer trajectories")
    except ValueError as e:
        raise UsageError(f"--plot-times = {args.plot_times!r}: {str(e).removeprefix('times: ')}") from None


def _warn(s):
    """Warnings on stderr after the run: the belt leaving a roller, an extrapolating transport, a
    steering actuator at the end of its range."""
    for c in s.get("control", []):
        if c["saturated"]:
            walk = c.get("sensor_walk_um_s")
            print(f"jaxbelt: warning: steering loop {c['actuator']}/{c['axis']} saturated: the actuator sat at its "
                  f"±{c['limit_mrad']:g} mrad range for {100 * c['saturated_fraction']:.0f} % of the run"
                  + (f", the belt still walks {walk:.3g} µm/s at the sensor" if walk is not None else "")
                  + "; the disturbance needs more steering range", file=sys.stderr)
    off = s["belt_off_roller"]
    if off:
        print(f"jaxbelt: warning: the belt runs off {off['roller']!r} at step {off['step']} (t = {off['t_s']:g} s): "
              f"its edge is {-off['margin_um'] / 1e3:.3g} mm beyond the roller's face; later results are not physical",
              file=sys.stderr)
    lo, hi = s["transport_weight_range"]
    if lo < 0 or hi >= 1:
        print(f"jaxbelt: warning: the {s['transport']!r} transport step extrapolated (weights in [{lo:.3g}, {hi:.3g}], "
              f"outside [0, 1)); the results are not reliable. Use {_transport_advice(s)}.", file=sys.stderr)


def _transport_advice(s) -> str:
    """What lowers the transport step's interpolation weights back into [0, 1)."""
    return "a smaller dt" + (" or --transport shift" if s["transport"] != "shift" else "")


def _text(s, scene, model, demo):
    def print_text(s):
        print(f"{'demo: ' if demo else ''}simulated {scene.name} ({scene.kind}, N = {model.n_unknowns}) for "
              f"{s['t_end_s']:g} s in {s['n_steps']} steps with the {s['integrator']} integrator: "
              f"{s['wall_s']:.2f} s run + {s['compile_s']:.2f} s compile")
        print(f"  max |tracer u| = {s['tracer_u_max_abs_um']:.6g} µm; roller surface speeds "
              + ", ".join(f"{k}: {v:.6g} m/s" for k, v in s["roller_speed_m_s"].items()))
        print(f"  belt mass {s['belt_mass_kg']:.9g} kg, max relative drift {s['belt_mass_rel_drift']:.2e}")
        for c in s.get("control", []):
            print(f"  steering {c['actuator']}/{c['axis']}: sensor {c['sensor_um_final']:.4g} µm at the end, angle "
                  f"{c['u_mrad_final']:.4g} mrad (max {c['u_mrad_max']:.4g} of ±{c['limit_mrad']:g})"
                  + (" SATURATED" if c["saturated"] else ""))

    return print_text


def _check_outputs(args):
    """The output options checked before anything is built: their folders exist, the figures'
    formats are written by matplotlib, ``--out`` names the ``.npz`` written; options that only
    shape an output not asked for are refused rather than ignored."""
    args.out = output_file("--out", args.out, kind="npz")
    for option in ("plot", "plot_fields", "plot_3d"):
        if getattr(args, option, None) is not None:
            setattr(args, option, output_file("--" + option.replace("_", "-"), getattr(args, option)))
    if getattr(args, "plot_times", None) is not None and not args.plot:
        raise UsageError(f"--plot-times = {args.plot_times!r}: needs --plot")
    if getattr(args, "exaggerate", 1.0) != 1.0 and not getattr(args, "plot_3d", None):
        raise UsageError(f"--exaggerate = {args.exaggerate:g}: needs --plot-3d")


EXTRAPOLATION_REFUSED = 0.5  # transport weights this far outside [0, 1): the run is refused (exit 3), not warned


def run(args, demo=False):
    _check_outputs(args)
    scene, mesh, model, options = load_run(args.scene, args.t_end, args.dt, args.integrator,
                                           getattr(args, "transport", None), getattr(args, "solver", None))
    # the 1D counterpart where the answer allows, unless fields of the 2D belt are asked for
    fields_asked = bool(getattr(args, "plot_fields", None) or getattr(args, "plot_3d", None))
    if getattr(args, "start", None) is not None:  # the start is the scene's: every run of it, the chooser's too
        scene = scene.replace(time=dataclasses.replace(scene.time, start=args.start))
    t_from = getattr(args, "accuracy_from", 0.0)
    if not (math.isfinite(t_from) and 0.0 <= t_from < scene.time.t_end):
        raise UsageError(f"--from = {t_from}: must lie in [0, {scene.time.t_end:g}) s, the run's time")
    chosen = choose_accuracy(args, scene, allow_1d=not fields_asked, allow_float32=True, t_from=t_from)
    with precision_scope("float64" if chosen is None else chosen.precision):
        if chosen is not None:
            scene, mesh, model, options = rebuild(chosen.scene)
        return _run(args, demo, scene, mesh, model, options, chosen)


def _run(args, demo, scene, mesh, model, options, chosen):
    request = _field_request(args, scene, options)  # checked before anything is compiled
    spans = span_forces(scene, mesh, model)
    slack, overstrained = slack_spans(scene, mesh, model, spans), overstrained_spans(scene, mesh, model, spans)
    if slack:  # before the run: the user learns it even if the run is long
        print(f"jaxbelt: warning: {slack_message(slack)}; the linear model carries compression like "
              "tension, so the results are not a real belt's", file=sys.stderr)
    if overstrained:
        print(f"jaxbelt: warning: {overstrain_message(overstrained)}", file=sys.stderr)
    swing = _start_swing(scene, mesh, options)
    progress = getattr(args, "progress", False) or (not args.json and sys.stderr.isatty())
    y0 = None if scene.time.start == "rest" else initial_state(model, start=scene.time.start)
    chunked = simulate_in_chunks(model, **options, y0=y0, field_rows=None if request is None else request["rows"],
                                 progress=progress)
    traj, fields = chunked.trajectory, chunked.fields
    s = _summary(scene, options, model, traj, {"compile_s": chunked.compile_s, "run_s": chunked.run_s})
    s["slack"], s["overstrained"] = slack, overstrained
    s["start_swing_left"] = None if swing is None else {name: left for name, _, left in swing}
    try:
        check_finite(traj, options.dt)
    except NonFiniteStateError as e:
        raise SimulationError(f"{e} (transport weights {s['transport_weight_range']})") from None
    lo, hi = s["transport_weight_range"]
    if lo < -EXTRAPOLATION_REFUSED or hi > 1 + EXTRAPOLATION_REFUSED:  # not a slight overshoot: no answer
        raise SimulationError(f"the {s['transport']!r} transport step extrapolated by more than half an element "
                              f"(weights in [{lo:.3g}, {hi:.3g}]): the run diverged and its results are not a "
                              f"solution; use {_transport_advice(s)}")
    if chosen is not None:
        s["chosen"] = chosen.to_dict()
        s["discretisation_error_um"] = s["chosen"].pop("discretisation_error_um")
    elif getattr(args, "error_estimate", False):
        s["discretisation_error_um"] = error_estimate(args, scene)
    if args.out:
        _write_npz(args.out, traj, mesh, model, request, fields)
        s["out"] = str(Path(args.out))
    if args.plot:
        _plot_tracers(args, scene, mesh, traj)
        s["plot"] = str(args.plot)
    if request is not None:
        s["field_times_s"] = [float(v) for v in request["t"]]
        _plot_fields(args, scene, mesh, model, traj, request, fields, s)
    emit(args, s, _text(s, scene, model, demo))
    if not args.json:
        print_accuracy(s)
    _warn(s)
    if not args.json:
        for k in ("out", "plot", "plot_fields", "plot_3d"):
            if k in s:
                print(f"  wrote {s[k]}")
    return 0
