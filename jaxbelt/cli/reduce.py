"""``jaxbelt reduce``: train a reduced model (pod, dmd, dmdc, pdmd) and compare it with the full one
(:func:`jaxbelt.rom.reduce_and_compare` does the work; this module reads the options and prints)."""

from __future__ import annotations

import argparse
import sys
import warnings
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from .. import plot, rom
from ..bench.reduction import reduce_and_time, warm_full_runs
from ..build import build_model
from ..integrators import DirectBackwardEuler, Reuse
from ..design.sampling import distribution_from_dict
from ..infra.results import to_json
from ..rom.comparison import FullRunDivergedError, ReducedRunDivergedError
from ..timeloop import RunOptions
from ._common import (SCENE_HELP, SimulationError, UsageError, check_at_least, emit, finite_or_none, fmt,
                      output_file, scene_from_args)
from ._design import read_toml

REDUCTIONS = {"pod": rom.ReducedPOD, "dmd": rom.DMD, "dmdc": rom.DMDc, "pdmd": rom.ParametricDMD}
"""The reductions by their --method name."""

REDUCE_HELP = """\
Train a reduced model and compare its tracer displacements with the full model's.

methods:
  pod   fully reduced POD step (solve and transport projected; jaxbelt.rom.fit_reduced_pod),
        trained on the first --train-steps steps of SCENE, or of the --train scenes (several
        configurations: the basis is linearised at the first one and run with SCENE's
        parameters); predicts all --steps steps from SCENE's initial state.
  dmd   exact DMD of SCENE's own pre-transport snapshots (one configuration): trains on the
        first --train-steps steps, predicts the rest from the last training snapshot; modes
        with |λ| > 1 + 1e-5 are discarded (jaxbelt.rom.DMDModel.stable; the static offset
        lives on a mode at λ ≈ 1).
  dmdc  DMD with control (inputs: the configuration parameters), trained on the --train scenes.
  pdmd  parametric DMD (one DMD per --train scene, interpolated in parameter space).

--train-ranges FILE.toml trains one model over a box of misalignments instead of --train scenes:
the file has the sweep's --dist format (uniform half-widths give the box, a normal law ±3σ), the
box is centred on SCENE's aligned machine, and the training runs are the axial design — the
aligned machine and each component at ± its half-width (jaxbelt.rom.axial_design); SCENE's own
misalignment is the configuration predicted (a warning if it lies outside the box). With dmdc
(and neither --train-steps nor --modes given) the training is sized to the question: training
steps and modes grow in levels until the calibrated error estimate on --held-out configurations
drawn from the box is below a tenth of --tol-um (jaxbelt.rom.train_over_box); the levels are
reported on stderr and in the JSON (sizing).

dmdc and pdmd predict a configuration they have not seen: --train needs at least two scenes,
the nominal configuration plus one run per varied parameter, e.g. for a two-roller-1d-* scene
  --train two-roller-1d two-roller-1d-train1
(dmdc is valid at the drive speed(s) it was trained at; vary drive speeds with pdmd).

The error is the tracer RMSE in µm over the predicted steps (the source's tolerance: 20 µm).
The error estimate (--stride K > 0; jaxbelt.rom.error_estimate.error_rom) needs no reference run: the
reduced trajectory's full-order residuals, averaged over windows of K steps (step by step where
the window mean still changes, as on the start-up), are propagated through the full step's
Jacobian in a residual-enriched subspace (with the quasi-static response of a settled
residual), and multiplied by a safety
factor calibrated on the training data (the same fit on the first half of the training window,
predicting the training runs over the whole window). error_estimate_um estimates rmse_um,
error_estimate_max_um max_rmse_over_time_um; effectivity = error_estimate_um / rmse_um.

Times exclude compilation on both sides (as with a warm compilation cache; the first calls,
compilation included, are reported apart): the full run in the scene's own mode and in the
reuse mode (frozen factors), offline = snapshot runs (in the fastest full mode) + fit, online =
the reduced prediction.
Speedups: "speedup total" = the fastest full mode that reproduces the scene's own mode to
1e-3 µm / (offline + online) — the honest figure; "vs scene mode" the same against the scene's
own mode; "eq. 7.5" the source's step-count formula n / (n_train + n_predicted / s), s the
per-step online speedup against the fastest full mode.
"""


def add_parser(subparsers):
    r = subparsers.add_parser("reduce", help="train a reduced model (pod, dmd, dmdc, pdmd): accuracy and speedup vs the full one",
                              description=REDUCE_HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    r.add_argument("scene", help=f"{SCENE_HELP}: the configuration to predict")
    r.add_argument("--method", choices=tuple(REDUCTIONS), required=True)
    r.add_argument("--train", nargs="+", default=None, metavar="SCENE",
                   help="training scenes (pod: default SCENE itself; dmdc/pdmd: required, at least two: the nominal "
                        "configuration plus one run per varied parameter)")
    r.add_argument("--train-ranges", default=None, metavar="FILE.toml",
                   help="train over a box of misalignments around SCENE's aligned machine (the sweep's --dist "
                        "format; uniform half-widths give the box, normal laws ±3σ): the axial design, 2P + 1 runs")
    r.add_argument("--tol-um", type=float, default=None, metavar="UM",
                   help="with --train-ranges and dmdc: train until the error estimate (tracer RMSE, µm) on held-out "
                        "configurations is below a tenth of this tolerance (default 20 µm, the source's)")
    r.add_argument("--held-out", type=int, default=None, metavar="K",
                   help="with --train-ranges and dmdc: configurations drawn from the box the estimate is checked "
                        "on (default 10)")
    r.add_argument("--modes", type=int, default=None, metavar="N",
                   help="reduced dimension (default: pod 20, dmdc/pdmd 30, dmd all non-negligible)")
    r.add_argument("--train-steps", type=int, default=None, metavar="N", help="full-order steps per training scene "
                   "(default min(200, steps/2))")
    r.add_argument("--steps", type=int, default=None, metavar="N",
                   help="steps to predict and compare (default: the scene's t_end / dt)")
    r.add_argument("--stride", type=int, default=10, metavar="K",
                   help="error estimate from residuals averaged over windows of K steps (0: no estimate; default 10)")
    r.add_argument("--plot", default=None, metavar="FILE.png",
                   help="write singular values / eigenvalues / error over time to this .png")
    r.add_argument("--json", action="store_true", help="print a JSON summary")
    r.set_defaults(func=run)
    return r


def run(args):
    _check_args(args)
    scene = scene_from_args(args.scene)
    test, opts = build_model(scene), RunOptions.from_scene(scene)
    train_names, train, train_solvers, box = _training_set(args, scene, test, opts)
    n = int(args.steps or opts.n_steps)
    trained = None
    if _sized(args):
        trained = _sized_training(test, box, n, opts, args)
        train_names = [train_names[0] + f", sized to {args.tol_um:g} µm on {args.held_out} held-out configurations"]
    m_train = trained.train_steps if trained is not None else int(args.train_steps or min(200, n // 2))
    modes = trained.modes if trained is not None else args.modes
    method = REDUCTIONS[args.method]() if modes is None else REDUCTIONS[args.method](modes=modes)
    try:  # the method's own check, in the options' words
        method.check(n, m_train)
    except ValueError as e:
        raise UsageError(str(e).replace("train_steps", "--train-steps").replace("n_steps", "--steps")) from None
    config = rom.ReduceConfig(method=method, options=opts.replace(n_steps=n), train_steps=m_train, stride=args.stride,
                              spectra=bool(args.plot))
    try:
        result = reduce_and_time(test, train, config, train_solvers, trained=trained)
    except FullRunDivergedError:
        raise SimulationError(f"the full simulation of {scene.name} diverged; nothing to compare with") from None
    except ReducedRunDivergedError as e:
        raise SimulationError(str(e)) from None
    report = _report(result, scene.name, train_names, args.stride, trained)
    if args.plot:
        _plot(result.result, report, args.plot)

    def print_text(report):
        print(f"reduced {scene.name} ({scene.kind}, N = {test.n_unknowns}) with {args.method}:")
        print_reduce(report)

    emit(args, report, print_text)
    return 0


def _check_args(args):
    """The options alone (before any scene is read)."""
    method = args.method
    check_at_least("--modes", args.modes)
    check_at_least("--steps", args.steps)
    check_at_least("--train-steps", args.train_steps, 2 if method == "dmd" else 1)
    check_at_least("--stride", args.stride, 0)
    check_at_least("--held-out", args.held_out)
    if args.tol_um is not None and not (np.isfinite(args.tol_um) and args.tol_um > 0):
        raise UsageError(f"--tol-um {args.tol_um}: must be a positive number of micrometres")
    for name, v in (("--tol-um", args.tol_um), ("--held-out", args.held_out)):
        if v is not None and not _sized(args):
            raise UsageError(f"{name} sizes the training of --method dmdc --train-ranges (without --train-steps or "
                             "--modes); it has no effect here")
    args.tol_um = 20.0 if args.tol_um is None else args.tol_um
    args.held_out = 10 if args.held_out is None else args.held_out
    train = list(args.train or [])
    if args.train_ranges is not None:
        if train:
            raise UsageError("--train and --train-ranges exclude each other (scenes, or a box of misalignments)")
        if method == "dmd":
            raise UsageError("--method dmd fits one configuration; use pod, dmdc or pdmd with --train-ranges")
    elif method in ("dmdc", "pdmd") and len(train) < 2:
        raise UsageError(f"--method {method} needs --train with at least two scenes (the nominal configuration plus "
                         f"one run per varied parameter), e.g. --train two-roller-1d two-roller-1d-train1")
    if method == "dmd" and any(t != args.scene for t in train):
        raise UsageError("--method dmd fits one configuration, the scene's own first --train-steps steps; "
                         "use dmdc or pdmd (or pod) to train on other scenes")
    output_file("--plot", args.plot)


def _sized(args) -> bool:
    """Whether the training is sized to the tolerance: dmdc over --train-ranges, neither
    --train-steps nor --modes given."""
    return args.train_ranges is not None and args.method == "dmdc" and args.train_steps is None and args.modes is None


def _training_set(args, scene, test, opts):
    """``(names, models, solvers)`` of the training runs: the --train scenes (default SCENE
    itself), or the axial design over the --train-ranges box; each checked against SCENE."""
    if args.train_ranges is not None:
        try:
            dist = distribution_from_dict(read_toml(args.train_ranges, "--train-ranges"), test)
        except ValueError as e:
            raise UsageError(f"--train-ranges {args.train_ranges}: {e}") from None
        box = rom.box_from_distribution(dist)
        models, _, space = rom.axial_design(test, dist.labels, box)
        where, unvaried = rom.position_in_box(test, space, box)
        if np.any(np.abs(where) > 1 + 1e-9) or unvaried:
            worst = space.labels()[int(np.argmax(np.abs(where)))]
            warnings.warn(f"{scene.name} lies outside the training box ({worst} at {np.max(np.abs(where)):.2f} of its "
                          f"half-width" + (f"; not varied: {', '.join(unvaried)}" if unvaried else "") + ")")
        names = [f"axial design over {args.train_ranges} ({len(models)} runs, {space.size} components)"]
        runs = [(names[0], m, opts) for m in models]
        box_spec = (tuple(dist.labels), box)
    else:
        box_spec = None
        names = list(args.train or [args.scene])
        runs = [(t, test, opts) if t == args.scene else _scene_run(t) for t in names]
    for name, m, o in runs:
        if m.n_unknowns != test.n_unknowns or m.kind != test.kind or m.n_tracers != test.n_tracers:
            raise UsageError(f"--train {name}: {m.kind} model with N = {m.n_unknowns} and {m.n_tracers} tracers; "
                             f"{scene.name} has {test.kind}, N = {test.n_unknowns}, {test.n_tracers} tracers "
                             "(training scenes need the same mesh)")
        if o.dt != opts.dt:
            raise UsageError(f"--train {name}: dt = {o.dt:g} s, {scene.name} has dt = {opts.dt:g} s")
        if args.method == "pod" and o.solver.transport != "shift":
            raise UsageError(f"--method pod needs the 'shift' transport rule; {name} uses {o.solver.transport!r}")
    outside = rom.parameters_outside_training(test, [m for _, m, _ in runs]) if (
        box_spec is None and args.method in ("dmdc", "pdmd") and len(runs) >= 2) else []
    if outside:
        warnings.warn(f"{scene.name} lies outside its training configurations ({'; '.join(outside[:3])}"
                      + (f"; {len(outside) - 3} more" if len(outside) > 3 else "")
                      + f"): --method {args.method} extrapolates there; read the error estimate")
    return names, [m for _, m, _ in runs], [o.solver for _, _, o in runs], box_spec


def _sized_training(test, box, n_steps, opts, args):
    """The DMDc model over the box trained until its held-out estimate meets the tolerance
    (:func:`jaxbelt.rom.train_over_box`), each level reported on stderr. The training runs and
    estimates use the reuse mode of a direct scene solver (factors frozen at each run's start;
    ``reduce`` checks that the mode reproduces the scene's own on the predicted run). The error
    estimate's full-order programs and the full runs ``reduce`` times afterwards are compiled, not
    run, in a background thread during the sizing (:func:`jaxbelt.rom.warm_error_rom`,
    :func:`jaxbelt.rom.warm_full_runs`): only one thread executes programs at a time."""
    labels, half_widths = box
    solver = opts.solver
    if isinstance(solver, DirectBackwardEuler):
        solver = DirectBackwardEuler(Reuse(), transport=solver.transport)

    def progress(level):
        worst = max(level.estimate_um)
        print(f"  sizing: {level.train_steps} steps × {len(labels) * 2 + 1} runs, {level.modes} modes: "
              f"estimate {worst:.3g} µm on held-out {len(level.estimate_um)}/{args.held_out} "
              f"({'meets' if level.passed else 'misses'} {args.tol_um / 10:g} µm; {level.seconds:.1f} s)",
              file=sys.stderr, flush=True)

    def warm_up():  # compiled on the other core meanwhile: the estimate's full-order programs, the full runs
        rom.warm_error_rom(test, opts.dt, solver)
        warm_full_runs(test, opts.solver, rom.ReduceConfig(method=rom.DMDc(), options=opts.replace(n_steps=n_steps),
                                                           train_steps=1))

    with ThreadPoolExecutor(max_workers=1) as pool:
        warm = pool.submit(warm_up)
        trained = rom.train_over_box(test, labels, half_widths, RunOptions(solver, n_steps, opts.dt), tol_um=args.tol_um,
                                     held_out=args.held_out, stride=max(args.stride, 1), progress=progress)
        warm.result()
    if not trained.converged:
        why = {"stalled": "more training stopped lowering the estimate", "horizon": "its window reached the horizon",
               "schedule": "at its largest level"}[trained.stop]
        warnings.warn(f"the sized training stopped ({why}: {trained.train_steps} steps, {trained.modes} modes) with a "
                      f"held-out estimate of {max(trained.levels[trained.chosen].estimate_um):.3g} µm, above the target "
                      f"{trained.target_um:g} µm")
    return trained


def _scene_run(name):
    scene = scene_from_args(name)
    return name, build_model(scene), RunOptions.from_scene(scene)


def _report(timed, scene_name: str, train_names, stride: int, trained=None) -> dict:
    """The command's JSON report of a result (what ``--json`` prints and the table shows): the
    result's own fields (:meth:`jaxbelt.bench.reduction.TimedReduction.to_dict`) with the scene,
    the training runs' names and the error estimate's summary."""
    r = timed.result
    report = timed.to_dict()
    for key in ("estimate", "cost", "spectra", "t", "error_um", "sizing", "modes_discarded", "training_starts_at_step"):
        report.pop(key)
    extra = {}
    if trained is not None:
        extra["sizing"] = dict(target_um=trained.target_um, converged=trained.converged, stop=trained.stop,
                               chosen_level=trained.chosen, held_out=len(trained.held_out), seconds=trained.seconds,
                               levels=to_json(trained.levels))
    if r.modes_discarded is not None:
        extra["modes_discarded"] = r.modes_discarded
    if r.training_starts_at_step is not None:
        extra["training_starts_at_step"] = r.training_starts_at_step
    e = r.estimate
    if e is not None:
        estimate = to_json(e)
        for key in ("error_um", "rmse_um", "max_um", "full_steps_predicted"):
            estimate.pop(key)
        estimate["cost"]["full_steps_predicted"] = e.full_steps_predicted
        extra["error_estimate"] = dict(
            method="error ROM (windowed full-order residuals through the step's Jacobian in a residual-enriched "
                   "subspace) x safety factor", **estimate)
    return dict(scene=scene_name, train=list(train_names), **extra, **report,
                error_estimate_um=None if e is None else _optional(e.rmse_um),
                error_estimate_max_um=None if e is None else _optional(e.max_um), stride=stride, n_test_configs=1)


def _optional(v):
    return None if v is None else finite_or_none(v)


def _plot(r: rom.ReductionResult, report: dict, path):
    """The --plot figure: singular values (modes marked), DMD eigenvalues, the error over time with
    the estimate."""
    s = r.spectra
    est = {} if r.estimate is None else dict(estimate_t=r.t, estimate_um=r.estimate.error_um)
    eigs = {} if s.eigs is None else dict(eigs=s.eigs, eig_weights=s.eig_weights)
    plot.plot_reduction(dict(report, modes=r.modes if s.marked is None else s.marked, rmse_um=r.rmse_um), r.t,
                        r.error_um, path, singular_values=s.singular_values, **eigs, **est)
    report["plot"] = str(path)


def print_reduce(r):
    rows = [
        ("scene", r["scene"]), ("method", r["method"]),
        ("trained on", ", ".join(r["train"]) + f" ({r['train_steps']} steps each)"),
        ("modes", str(r["modes"])
         + (f" ({r['modes_discarded']} unstable discarded)" if r.get("modes_discarded") else "")),
        ("predicted", f"{r['predict_steps']} steps from step {r['predict_from_step']} ({r['compared']})"),
        ("RMSE", fmt(r["rmse_um"], " µm")), ("RRMSE", fmt(r["rrmse"])),
        ("max RMSE over time", fmt(r["max_rmse_over_time_um"], " µm")),
        ("error estimate", (fmt(r["error_estimate_um"], " µm") + f" (max over time {fmt(r['error_estimate_max_um'], ' µm')}; "
                            f"effectivity {fmt(r['effectivity'])}, safety factor "
                            f"{fmt(r['error_estimate']['safety_factor'])})") if r.get("error_estimate_um") is not None
         else "-" if r["stride"] == 0 else "nan"),
    ]
    if "sizing" in r:
        sz = r["sizing"]
        last = sz["levels"][sz["chosen_level"]]
        rows.append(("sized", f"{len(sz['levels'])} level(s) in {sz['seconds']:.3g} s; held-out estimate "
                              f"{fmt(max(last['estimate_um']), ' µm')} on {len(last['estimate_um'])}/{sz['held_out']} "
                              f"({'meets' if sz['converged'] else 'misses'} {fmt(sz['target_um'], ' µm')})"))
    tm = r["timings"]
    modes = ", ".join(f"{f['mode']} {f['run_s']:.4g} s" for f in tm["full_runs"])
    rows += [("full run", f"{tm['full_run_s']:.4g} s ({tm['full_mode']}, the fastest; {modes})"),
             ("offline", f"{tm['offline_s']:.4g} s (snapshots + fit; first call with compilation "
                         f"{tm['offline_first_call_s']:.4g} s)"),
             ("online", f"{tm['online_s']:.4g} s"), ("speedup online", fmt(tm["speedup_online"], "×")),
             ("speedup total", fmt(tm["speedup_total"], "×") + f" (vs the scene's own mode "
                               f"{fmt(tm['speedup_total_vs_scene_mode'], '×')}; source's eq. 7.5: "
                               f"{fmt(tm['speedup_eq_7_5'], '×')})")]
    if "plot" in r:
        rows.append(("plot", r["plot"]))
    w = max(len(k) for k, _ in rows)
    for k, v in rows:
        print(f"  {k:<{w}}  {v}")
