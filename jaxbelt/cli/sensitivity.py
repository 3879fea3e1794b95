"""``jaxbelt sensitivity``: a metric and its gradient w.r.t. every roller misalignment component."""

from __future__ import annotations

from ..design import sensitivity_report
from ..infra.results import unit_key
from ._design import add_design_arguments, check_plot, finish, load_design_model, make_design_study, stage


def add_parser(subparsers):
    p = subparsers.add_parser("sensitivity", help="metric and its gradient w.r.t. every roller's misalignments "
                                                  "(reverse mode through the whole run)")
    add_design_arguments(p, "lateral_rms")
    p.set_defaults(func=run)
    return p


def run(args):
    check_plot(args.plot)
    model, options = load_design_model(args)
    stage(args, f"aligned reference run ({model.n_unknowns} unknowns)")
    study, _ = make_design_study(args, model, options)
    stage(args, "compiling and timing the forward run and the gradient")
    report = sensitivity_report(study)
    return finish(args, report.to_dict(), _print, "plot_sensitivity", report)


def _print(r):
    when = "in steady operation" if r["t_eval_s"] is None else f"at t = {r['t_eval_s']:g} s"
    unit = r["unit"]
    print(f"{r['metric']} = {r[unit_key('value_um', unit)]:.6g} {unit} {when} "
          f"(forward {r['forward_s']:.3g} s, gradient {r['gradient_s']:.3g} s = ×{r['gradient_s'] / r['forward_s']:.2f})")
    print(f"{'roller':14s} {f'translation x, y, z [{unit}/mm]':>36s}   {f'rotation x, y, z [{unit}/mrad]':>36s}")
    for name, g in r["gradient"].items():
        t = " ".join(f"{v:11.4g}" for v in g[unit_key("translation_um_per_mm", unit)])
        a = " ".join(f"{v:11.4g}" for v in g[unit_key("rotation_um_per_mrad", unit)])
        print(f"{name:14s} {t}   {a}")
    if r["at_kink"]:
        print("  (the machine is aligned: every metric has a kink there; shown are the one-sided slopes ≥ 0)")
    for z in r["structural_zero"]:
        print(f"  {z['component']}: structurally zero ({z['reason']})")
