"""``jaxbelt steering``: the plant of a scene's first steering loop, measured with the loop open."""

from __future__ import annotations

import json
import warnings

import numpy as np

from ..steering.report import SteeringWarning, steering_report
from ._common import UsageError, load_run

DEFAULT_SCENE = "two-roller-steered"


def add_parser(subparsers):
    p = subparsers.add_parser("steering", help="steering coefficient, disturbance, hold angle, walk sensitivity and "
                                               "identified plant of the first [[control]] loop (loop open)")
    p.add_argument("scene", nargs="?", default=DEFAULT_SCENE, help=f"scene name or TOML file (default {DEFAULT_SCENE})")
    p.add_argument("--t-end", type=float, default=None, metavar="S", help="run length, s (default: the scene's)")
    p.add_argument("--step", type=float, default=0.1, metavar="MRAD", help="actuator step, mrad (default 0.1)")
    p.add_argument("--no-sensitivity", action="store_true", help="skip the walk sensitivity (forward-mode run)")
    p.add_argument("--json", action="store_true", help="print the report as JSON")
    p.set_defaults(func=run)
    return p


def run(args):
    if not (np.isfinite(args.step) and args.step > 0):
        raise UsageError(f"--step = {args.step}: must be a positive number of mrad")
    scene, _, model, options = load_run(args.scene, t_end=args.t_end)
    if not scene.control:
        raise UsageError(f"scene {scene.name!r} has no [[control]] steering loop")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", SteeringWarning)
        report = steering_report(model, options, step_mrad=args.step, sensitivity=not args.no_sensitivity)
    for w in caught:
        warnings.warn(str(w.message), w.category, stacklevel=1)
    d = report.to_dict()
    if args.json:
        print(json.dumps(d))
    else:
        _print(d)
    return 0


def _print(r):
    print(f"loop {r['loop']} (open): walk rates of the steady walk, step response over {r['t_end_s']:g} s")
    print(f"  coefficient      {r['coefficient_mm_s_per_mrad']:+.6g} mm/s per mrad")
    print(f"  disturbance      {r['disturbance_mm_s']:+.6g} mm/s")
    print(f"  hold angle       {r['hold_angle_mrad']:+.6g} mrad (range ±{r['limit_mrad']:g} mrad)"
          + ("  SATURATED" if r["saturated"] else ""))
    p = r["plant"]
    print(f"  plant            k = {p['gain']:+.5g} m/s/rad, τ = {p['lag']:.4g} s, τ₂ = {p['lag2']:.4g} s, "
          f"z = {p['zero']:.4g} s, θ = {p['delay']:.4g} s, D = {p['feedthrough']:+.4g} m/rad")
    print(f"                   recirculation θ_r = {p['loop_delay']:.4g} s, τ_r = {p['loop_lag']:.4g} s "
          f"(transit {r['loop_time_s']:.4g} s); fit error {100 * r['plant_fit_error']:.2f} % of range")
    print(f"  P-loop margin    k_p < {r['response_gain_margin']:.4g} mrad/mm on the step response "
          f"(period {r['response_crossover_period_s']:.3g} s); {r['plant_gain_margin']:.4g} mrad/mm on the plant "
          f"with the hold's {1e3 * r['sample_delay_s']:.3g} ms (period {r['plant_crossover_period_s']:.3g} s)")
    if r["walk_sensitivity"] is not None:
        print(f"  {'roller':12s} {'translation x, y, z [mm/s per mm]':>36s}   {'rotation x, y, z [mm/s per mrad]':>36s}")
        for name, g in r["walk_sensitivity"].items():
            t = " ".join(f"{v:11.4g}" for v in g["translation_mm_s_per_mm"])
            a = " ".join(f"{v:11.4g}" for v in g["rotation_mm_s_per_mrad"])
            print(f"  {name:12s} {t}   {a}")
