"""``jaxbelt tolerance``: the largest box of roller tolerances that keeps a metric within a limit,
verified by full runs."""

from __future__ import annotations

from ..design import parameter_space, tolerance_box
from ..design.tolerance import box_discretisation, weights_from_dict
from ..infra.results import unit_key
from ._common import UsageError
from ._design import (add_design_arguments, add_steering_limit_argument, check_limit_arguments, check_steering_limit,
                      finer_model, finish, limits_of, load_design_model, make_design_study, read_toml, stage)


def add_parser(subparsers):
    p = subparsers.add_parser("tolerance", help="largest tolerance box keeping the metric within --limit-um, "
                                                "verified by full runs")
    add_design_arguments(p, "lateral_max", limit=True)
    add_steering_limit_argument(p)
    p.add_argument("--components", default=None,
                   help='which components get a tolerance, e.g. "roller 2:rotation,roller 3:dz,roller 1" '
                        "(default: every one that can vary)")
    p.add_argument("--weights", default=None, metavar="FILE.toml",
                   help='cost weights: [roller."NAME"] translation = [wx, wy, wz], rotation = [...] (default 1)')
    p.set_defaults(func=run)
    return p


def run(args):
    check_limit_arguments(args)
    weights_data = read_toml(args.weights, "--weights") if args.weights else None
    model, options = load_design_model(args)
    check_steering_limit(args, model)  # before any computation
    try:
        space = parameter_space(model, args.components)
        weights = None if weights_data is None else weights_from_dict(weights_data, space)
    except ValueError as e:
        raise UsageError(f"--components/--weights: {e}") from None
    stage(args, f"aligned reference run and its Jacobian ({model.n_unknowns} unknowns)")
    study, linear = make_design_study(args, model, options, args.components, jacobian=True)
    limit, limits = limits_of(args, study)
    stage(args, "box optimisation and verification runs")
    try:
        res = tolerance_box(study, limit, weights, limits=limits, linear=linear)
    except ValueError as e:  # the scene's own misalignment already breaks the limit
        raise UsageError(str(e)) from None
    out = res.to_dict()
    out["window_s"] = list(study.t_window) if study.steered and not study.steady else None
    out["operation"] = "steady" if study.steady else "time-stepped"
    if study.steady and study.jitter_mrad is not None:
        out["actuator_jitter_mrad"] = [float(x) for x in study.jitter_mrad]
        out["aligned_angle_mrad"] = [float(x) for x in study.ref_angle[0]]
    if not args.no_error_bars:
        stage(args, "error bars: the verified corners on the grid one level finer")
        fine, fine_options, grid, grid_fine = finer_model(args)
        bars = box_discretisation(res, study, fine, fine_options, grid=grid,
                                  grid_fine=grid_fine).to_dict()
        out["discretisation"] = bars
        for row, u in zip(out["half_widths"], bars["half_width_uncertainty"]):
            row["discretisation_uncertainty"] = u
    return finish(args, out, _print, "plot_tolerance_box", res)


def _print(r):
    unit = r["unit"]  # of the metric values: the metric's, the first limit's with several
    k = lambda name: unit_key(name, unit)  # noqa: E731  (their keys name it)
    if r["limits"]:
        held = ", ".join(f"{x['metric']} ≤ {x['limit']:g} {x['unit']}" for x in r["limits"])
        when = "in steady operation" if r["operation"] == "steady" else \
            f"over {r['window_s'][0]:g}–{r['window_s'][1]:g} s"
        print(f"largest box with {held} {when} (half-widths around the scene's misalignment):")
        if r.get("actuator_jitter_mrad"):
            print(f"  (the aligned machine's actuator jitter from sensor noise and edge profile, "
                  f"{max(r['actuator_jitter_mrad']):.3g} mrad, is held inside the range)")
    else:
        print(f"largest box with {r['metric']} ≤ {r[k('limit_um')]:g} {unit} at t = {r['t_eval_s']:g} s "
              f"(half-widths around the scene's misalignment):")
    for row in r["half_widths"]:
        note = " (not felt: capped)" if row["component"] in r["unconstrained"] else (
            f"  {100 * row['share']:.0f} % of the worst case" if row["share"] > 0 else "")
        bar = row.get("discretisation_uncertainty")
        bar = "" if bar is None or row["component"] in r["unconstrained"] else f" (± {bar:.2g} discretisation)"
        print(f"  {row['component']:16s} ± {row['half_width']:.4g} {row['unit']}{bar}{note}")
    how = "steady solves" if r["operation"] == "steady" else "full runs"
    print(f"verified worst case {r[k('worst_case_um')]:.4g} {unit} by {len(r['verification'])} {how} "
          f"({'within' if r['verified'] else 'NOT within'} [0.97, 1] × limit, {r['iterations']} iteration(s)); "
          f"linear model {r[k('predicted_worst_um')]:.4g} {unit}")
    for x in r["limits"]:
        print(f"  {x['metric']:17s} verified worst {x['worst_case']:.4g} {x['unit']} of {x['limit']:g} "
              f"({100 * x['ratio']:.0f} %; linear model {x['predicted_worst']:.4g}){'  <- binds' if x['binds'] else ''}")
    print(f"binding: {', '.join(r['binding'][:5]) or '-'}; RSS stack-up with σ = h/3: {r[k('rss_um')]:.4g} {unit}")
    d = r.get("discretisation")
    if d is not None:
        g = d["grid_fine"]
        print(f"discretisation: one level finer (n_xi {g['n_xi']}, n_eta {g['n_eta']}, dt {g['dt']:g} s) the worst corner "
              f"reads {d[k('worst_case_fine_um')]:.4g} against {d[k('worst_case_um')]:.4g} {unit}: the half-widths change by "
              f"{100 * d['half_width_relative_change']:+.2g} %")
    if not r["verified"]:
        print("warning: the verified worst case is outside [0.97, 1] × limit (strongly nonlinear response)")
