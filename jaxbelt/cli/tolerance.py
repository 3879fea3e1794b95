"""``jaxbelt tolerance``: the largest box of roller tolerances that keeps a metric within a limit,
verified by full runs."""

from __future__ import annotations

from ..design import parameter_space, tolerance_box
from ..design.tolerance import weights_from_dict
from ._common import UsageError
from ._design import (add_design_arguments, check_limit, check_plot, finish, load_design_model, make_design_study,
                      read_toml, stage)


def add_parser(subparsers):
    p = subparsers.add_parser("tolerance", help="largest tolerance box keeping the metric within --limit-um, "
                                                "verified by full runs")
    add_design_arguments(p, "lateral_max", limit=True)
    p.add_argument("--components", default=None,
                   help='which components get a tolerance, e.g. "roller 2:rotation,roller 3:dz,roller 1" '
                        "(default: every one that can vary)")
    p.add_argument("--weights", default=None, metavar="FILE.toml",
                   help='cost weights: [roller."NAME"] translation = [wx, wy, wz], rotation = [...] (default 1)')
    p.set_defaults(func=run)
    return p


def run(args):
    check_limit(args.limit_um)
    check_plot(args.plot)
    weights_data = read_toml(args.weights, "--weights") if args.weights else None
    model, options = load_design_model(args)
    try:
        space = parameter_space(model, args.components)
        weights = None if weights_data is None else weights_from_dict(weights_data, space)
    except ValueError as e:
        raise UsageError(f"--components/--weights: {e}") from None
    stage(args, f"aligned reference run ({model.n_unknowns} unknowns)")
    study = make_design_study(args, model, options, args.components)
    stage(args, "Jacobian, box optimisation and verification runs")
    try:
        res = tolerance_box(study, args.limit_um, weights)
    except ValueError as e:  # the scene's own misalignment already breaks the limit
        raise UsageError(str(e)) from None
    return finish(args, res.to_dict(), _print, "plot_tolerance_box", res)


def _print(r):
    print(f"largest box with {r['metric']} ≤ {r['limit_um']:g} µm at t = {r['t_eval_s']:g} s "
          f"(half-widths around the scene's misalignment):")
    for row in r["half_widths"]:
        note = " (not felt: capped)" if row["component"] in r["unconstrained"] else (
            f"  {100 * row['share']:.0f} % of the worst case" if row["share"] > 0 else "")
        print(f"  {row['component']:16s} ± {row['half_width']:.4g} {row['unit']}{note}")
    print(f"verified worst case {r['worst_case_um']:.4g} µm by {len(r['verification'])} full runs "
          f"({'within' if r['verified'] else 'NOT within'} [0.97, 1] × limit, {r['iterations']} iteration(s)); "
          f"linear model {r['predicted_worst_um']:.4g} µm")
    print(f"binding: {', '.join(r['binding'][:5]) or '-'}; RSS stack-up with σ = h/3: {r['rss_um']:.4g} µm")
    if not r["verified"]:
        print("warning: the verified worst case is outside [0.97, 1] × limit (strongly nonlinear response)")
