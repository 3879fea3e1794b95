"""Options and set-up shared by the tolerance-design commands (``sensitivity``, ``tolerance``,
``sweep``): the scene, the metric and its evaluation time, the solver, and the checks that turn
bad input into one line and exit code 2 before anything is computed or written."""

from __future__ import annotations

import math
import sys
import tomllib
from pathlib import Path

from .. import plot
from ..accuracy import refine, scene_grid
from ..design import METRICS, make_study
from ..design.metrics import CLOSED_LOOP_WINDOW, OPEN_LOOP_WINDOW
from ..registry import LINEAR_SOLVERS
from ._accuracy import add_accuracy_arguments, choose_accuracy, print_accuracy
from ._common import SCENE_HELP, UsageError, emit, load_run, output_file, rebuild

DESIGN_SCENE = "three-roller-steered"


def add_design_arguments(p, metric_default: str, limit: bool = False):
    p.add_argument("scene", nargs="?", default=DESIGN_SCENE,
                   help=f"{SCENE_HELP} (default {DESIGN_SCENE}: the aligned three-roller machine with its "
                        "steering loop closed, judged in steady operation)")
    p.add_argument("--metric", default=None,
                   help=f"{' | '.join(METRICS)} (default {metric_default}; on a 1D scene, which has no lateral "
                        f"deviation, {one_d_metric(metric_default)})")
    p.set_defaults(metric_default=metric_default)
    p.add_argument("--at", type=float, default=None, metavar="T",
                   help="evaluation time in s (default: the scene's end); on a steered machine, judge this time of "
                        "a time-stepped run instead of steady operation")
    p.add_argument("--window", type=float, default=None, metavar="S",
                   help="steered machine: judge the last S seconds before --at of a time-stepped run (the "
                        "transient question) instead of steady operation (the default)")
    p.add_argument("--solver", choices=tuple(LINEAR_SOLVERS), default=None,
                   help="linear solver of the runs (default: the scene's, kept-interior unless it names one; "
                        "reuse: the first step's factors kept, refined every step)")
    if limit:
        p.add_argument("--limit-um", type=float, default=20.0,
                       help="limit on the metric, µm (default 20); tolerance on a steered machine: on the lateral "
                            "and the longitudinal deviation both")
    add_accuracy_arguments(p, estimate=False)
    if limit:
        p.add_argument("--no-error-bars", action="store_true",
                       help="skip the discretisation error bars (the answer re-evaluated on the grid one level finer "
                            "in n_xi, n_eta and dt)")
    p.add_argument("--json", action="store_true", help="one JSON object on stdout")
    p.add_argument("--plot", default=None, metavar="FILE.png")
    p.add_argument("--progress", action="store_true", help="progress bars and stage messages on stderr")


def add_steering_limit_argument(p):
    p.add_argument("--steering-limit-mrad", type=float, default=None,
                   help="steered machine: limit on the steering actuator's angle, mrad (default: its range, so no "
                        "answer counts on a saturated actuator)")


def check_steering_limit(args, model=None):
    """``--steering-limit-mrad`` a positive number, and (with ``model``) on a machine with a loop."""
    x = args.steering_limit_mrad
    if x is not None and not (math.isfinite(x) and x > 0):
        raise UsageError(f"--steering-limit-mrad = {x}: must be a positive number")
    if x is not None and model is not None and model.control is None:
        raise UsageError(f"--steering-limit-mrad = {x}: the scene has no steering loop")


def limits_of(args, study):
    """``(limit, limits)``: the study metric's limit and the further limits held at the same time.
    On a steered machine a lateral (longitudinal) max-type metric is joined by the other direction
    at ``--limit-um`` and by ``steering_max`` at ``--steering-limit-mrad`` (default: the range);
    ``--metric steering_max`` takes ``--steering-limit-mrad`` as its limit. Otherwise one limit."""
    if not study.steered:
        if args.steering_limit_mrad is not None:
            raise UsageError(f"--steering-limit-mrad = {args.steering_limit_mrad}: the scene has no steering loop")
        return args.limit_um, {}
    steer = study.range_mrad if args.steering_limit_mrad is None else args.steering_limit_mrad
    if args.metric == "steering_max":
        return steer, {}
    metric = METRICS.get(args.metric)
    if metric is None or metric.aggregate != "max" or metric.other_direction is None:
        return args.limit_um, {}
    return args.limit_um, {metric.other_direction: args.limit_um, "steering_max": steer}


def one_d_metric(metric: str) -> str:
    """The longitudinal counterpart of a lateral metric (its ``other_direction``): the default on a
    1D scene."""
    m = METRICS[metric]
    return m.other_direction if m.needs_2d and m.other_direction is not None else metric


def check_limit(v):
    if not (math.isfinite(v) and v > 0):
        raise UsageError(f"--limit-um = {v}: must be a positive number")


def check_limit_arguments(args):
    """The checks of a command that judges limits (``tolerance``, ``sweep``) before any file is
    read: ``--limit-um``, ``--steering-limit-mrad`` and ``--plot``."""
    check_limit(args.limit_um)
    check_steering_limit(args)
    check_plot(args.plot)


def check_plot(path):
    output_file("--plot", path)


def read_toml(path, option):
    try:
        return tomllib.loads(Path(path).read_text())
    except FileNotFoundError:
        raise UsageError(f"{option} = {str(path)!r}: no such file") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise UsageError(f"{option} = {str(path)!r}: not valid TOML ({e})") from None


def load_design_model(args):
    """``(model, options)`` of ``args.scene`` with ``--solver`` (scene errors → exit 2): its model
    and its run settings (:class:`jaxbelt.RunOptions`)."""
    if args.at is not None and not (math.isfinite(args.at) and args.at > 0):
        raise UsageError(f"--at = {args.at}: must be a positive time in s")
    if args.window is not None and not (math.isfinite(args.window) and args.window > 0):
        raise UsageError(f"--window = {args.window}: must be a positive time in s")
    scene, _, model, options = load_run(args.scene, linear_solver=args.solver)
    if args.window is not None and not scene.control:
        raise UsageError(f"--window = {args.window}: the scene has no steering loop (its metrics read one instant, "
                         "--at)")
    if args.window is not None and args.window > (options.t_end if args.at is None else args.at) + 1e-12:
        raise UsageError(f"--window = {args.window}: longer than the run it reads "
                         f"({options.t_end if args.at is None else args.at:g} s)")
    if args.metric is None:
        args.metric = one_d_metric(args.metric_default) if scene.kind == "1d" else args.metric_default
    if args.metric in METRICS:  # an unknown metric is reported by make_design_study
        # the metric reads the window before t_eval: the error is asked there, not at the start-up
        t_eval = scene.time.t_end if args.at is None else args.at
        frac = CLOSED_LOOP_WINDOW if scene.control else OPEN_LOOP_WINDOW
        if args.window is not None:
            frac = min(1.0, args.window / t_eval)
        chosen = choose_accuracy(args, scene, metric_quantities(args.metric, scene), t_from=(1 - frac) * t_eval,
                                 allow_reuse=False)
        if chosen is not None:
            scene, _, model, options = rebuild(chosen.scene)
            args.accuracy_chosen = chosen.to_dict()
    args.design_scene = scene
    return model, options


def finer_model(args):
    """``(model, options, grid, grid_fine)``: ``args``' scene on the grid one level finer in every
    direction (elements along and across ×2, Δt / 2: the CFL number kept), its run settings, and
    the two grids as dicts — for the design answers' discretisation error bars."""
    scene = args.design_scene
    fine = refine(scene, n_xi=2.0, n_eta=2.0, dt=2.0)
    _, _, model, options = rebuild(fine)
    grid, grid_fine = (scene_grid(s) for s in (scene, fine))
    return model, options, grid, grid_fine


def metric_quantities(metric: str, scene) -> tuple[str, ...]:
    """The tracer quantities whose discretisation error a design metric carries: the lateral
    deviation, the longitudinal one, or (the steering angle, which answers the lateral walk, and a
    steered machine's several limits) both."""
    own = METRICS[metric].quantities
    if scene.kind == "1d" or own == ("longitudinal",):
        return ("longitudinal",)
    return ("longitudinal", "lateral") if scene.control else own


def make_design_study(args, model, options, components=None, jacobian: bool = False):
    """:func:`jaxbelt.design.make_study` at ``--at`` (default the scene's end) with the scene's
    time step and solver, its ``ValueError``s as usage errors. **Returns:** ``(study, linear)``:
    with ``jacobian`` ``linear`` is its :class:`~jaxbelt.design.LinearDeviation` (for a tolerance
    box, FORM), else ``None``."""
    if args.metric not in METRICS:
        raise UsageError(f"--metric = {args.metric!r}: unknown (one of {', '.join(METRICS)})")
    if args.at is not None and args.at > options.t_end + 1e-12:
        raise UsageError(f"--at = {args.at}: after the scene's end ({options.t_end:g} s); lengthen [time] t_end_s")
    steady = judges_steady_operation(args, model)
    t_eval = args.at if args.at is not None else options.t_end
    fraction = None if args.window is None else args.window / t_eval
    try:
        if steady:
            made = make_study(model, args.metric, options, components=components, jacobian=jacobian, steady=True)
        else:
            made = make_study(model, args.metric, options, t_eval=args.at, components=components, jacobian=jacobian,
                              window_fraction=fraction)
    except ValueError as e:  # NoSteadyStateError included: what was found, in one line
        raise UsageError(str(e)) from None
    return made if jacobian else (made, None)


def judges_steady_operation(args, model) -> bool:
    """Whether a design command judges steady operation: on a steered machine unless ``--at`` or
    ``--window`` asks for a time-stepped run."""
    return model.control is not None and args.at is None and args.window is None


def stage(args, text):
    if args.progress:
        print(f"jaxbelt: {text}", file=sys.stderr, flush=True)


def finish(args, out, print_text, plot_name, *plot_args):
    """Print ``out`` (JSON with ``--json``) and, with ``--plot``, draw ``jaxbelt.plot.<plot_name>(*plot_args,
    args.plot)``."""
    chosen = getattr(args, "accuracy_chosen", None)
    if chosen is not None:
        out["chosen"] = chosen
    emit(args, out, print_text)
    if chosen is not None and not args.json:
        print_accuracy({"chosen": chosen})
    if args.plot:
        getattr(plot, plot_name)(*plot_args, args.plot)
    return 0
