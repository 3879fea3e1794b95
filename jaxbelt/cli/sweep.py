"""``jaxbelt sweep``: Monte-Carlo yield under random roller misalignments, with FORM and (near
yield 1) importance sampling, stored chunk by chunk in a resumable Zarr store."""

from __future__ import annotations

from pathlib import Path

from ..design import distribution_from_dict, run_sweep, with_limits
from ..infra.results import unit_key
from ..infra.store import open_sweep
from ..design.sweep import sweep_identity, yield_discretisation
from ._common import UsageError
from ._design import (add_design_arguments, add_steering_limit_argument, check_limit_arguments, check_steering_limit,
                      finer_model, finish, judges_steady_operation, limits_of, load_design_model, make_design_study,
                      read_toml, stage)


def add_parser(subparsers):
    p = subparsers.add_parser("sweep", help="Monte-Carlo yield (+ FORM, importance sampling) for misalignment "
                                            "distributions")
    add_design_arguments(p, "lateral_max", limit=True)
    add_steering_limit_argument(p)
    p.add_argument("--dist", required=True, metavar="FILE.toml",
                   help='[roller."NAME"] rotation_mrad = {dist = "normal", sigma = [x, y, z]}, '
                        'translation_mm = {dist = "uniform", half_width = [x, y, z]}')
    p.add_argument("--samples", type=int, default=1000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--chunk", type=int, default=64, help="configurations per vmap batch (memory)")
    p.add_argument("--rom", default=None, help="off | auto: a reduced model stands in where validated (default: auto "
                                               "in steady operation, where it is the steady state's linear response, "
                                               "off for time-stepped runs)")
    p.add_argument("--no-form", action="store_true", help="skip FORM and importance sampling")
    p.add_argument("--out", default=None, metavar="DIR", help="Zarr store (appended per chunk; a rerun resumes)")
    p.set_defaults(func=run)
    return p


def run(args):
    check_limit_arguments(args)
    if args.samples < 1:
        raise UsageError(f"--samples = {args.samples}: must be at least 1")
    if args.chunk < 1:
        raise UsageError(f"--chunk = {args.chunk}: must be at least 1")
    if args.rom not in (None, "off", "auto"):
        raise UsageError(f"--rom = {args.rom!r}: one of off, auto")
    data = read_toml(args.dist, "--dist")
    model, options = load_design_model(args)
    check_steering_limit(args, model)
    try:
        dist = distribution_from_dict(data, model)
    except ValueError as e:
        raise UsageError(f"--dist {args.dist}: {e}") from None
    rom = args.rom or ("auto" if judges_steady_operation(args, model) else "off")
    if args.out is not None and Path(args.out).exists() and not Path(args.out).is_dir():
        raise UsageError(f"--out = {args.out!r}: exists and is not a directory")
    # FORM and the RSS stack-up read the linear response at θ = 0: taken with the reference run
    stage(args, f"aligned reference run{'' if args.no_form else ' and its Jacobian'} ({model.n_unknowns} unknowns)")
    study, linear = make_design_study(args, model, options, list(dist.labels), jacobian=not args.no_form)
    # the limits tolerance holds on the same machine (on a steered one: both directions and the actuator)
    limit, limits = limits_of(args, study)
    if limits:
        study = with_limits(study, ((args.metric, limit),) + tuple(limits.items()))
    if args.out is not None:
        try:  # a store of another study is refused before anything runs
            open_sweep(args.out, sweep_identity(study, dist, args.samples, limit, args.seed, args.scene))
        except ValueError as e:
            raise UsageError(str(e)) from None
    res = run_sweep(study, dist, args.samples, limit, seed=args.seed, chunk=args.chunk, out=args.out,
                    rom=rom, with_form=not args.no_form, progress=args.progress, scene=args.scene, linear=linear)
    out = res.to_dict()
    if not args.no_error_bars:
        stage(args, "error bar: the samples nearest the limit on the grid one level finer")
        fine, fine_options, grid, grid_fine = finer_model(args)
        out["discretisation"] = yield_discretisation(res, study, fine, fine_options, grid=grid,
                                                     grid_fine=grid_fine).to_dict()
    return finish(args, out, _print, "plot_yield", res.metric_values, limit, res)


def _print(r):
    lo, hi = r["ci95"]
    steered = r.get("saturated") is not None
    if r.get("limits"):
        held = ", ".join(f"{x['metric']} ≤ {x['limit']:g} {x['unit']}" for x in r["limits"])
        what = f"every limit held ({held})"
    else:
        what = f"{r['metric']} ≤ {r[unit_key('limit_um', r['unit'])]:g} {r['unit']}"
    print(f"yield {r['yield']:.4f} (95 % Wilson interval {lo:.4f}–{hi:.4f}): {r['passed']} of {r['samples']} "
          f"configurations with {what}" + (" and the steering within its range" if steered else ""))
    d = r.get("discretisation")
    if d is not None:
        print(f"discretisation bias of the yield {d['bias']:+.4f} (one level finer: {d['flipped']} of the {d['samples']} "
              f"samples nearest the limit change verdict; their metric moves by {100 * d['metric_relative_change']:.2g} %)")
    if steered:
        print(f"{r['saturated']} configuration(s) saturated the steering actuator (±{r['range_mrad']:g} mrad) "
              f"and count as failures; largest actuator angle {r['steering_max_mrad']:.4g} mrad")
    if "form_yield" in r:
        print(f"FORM: β = {r['form_beta']:.3f}, yield {r['form_yield']:.6f}; "
              f"linear RSS stack-up (3σ) {r[unit_key('rss_3sigma_um', r['unit'])]:.4g} {r['unit']}")
    if "is_yield" in r:
        print(f"importance sampling ({r['is_samples']} samples): yield {r['is_yield']:.6f} "
              f"(95 %: {r['is_ci95'][0]:.6f}–{r['is_ci95'][1]:.6f})")
    print(f"{r['full_runs']} full and {r['reduced_runs']} reduced runs in {r['wall_s']:.1f} s "
          f"({r['configs_per_s']:.2f} configurations/s)"
          + (f"; reduced model ×{r['speedup_estimate']:.1f} (estimate)" if "speedup_estimate" in r else ""))
