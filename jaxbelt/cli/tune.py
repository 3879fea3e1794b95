"""``jaxbelt tune``: PI gains of the steering loop fitted through the whole closed-loop run."""

from __future__ import annotations

from ..steering.tuning import OBJECTIVES, tune
from ._common import SCENE_HELP, UsageError, check_at_least, emit, fmt, load_run


def add_parser(subparsers):
    p = subparsers.add_parser("tune", help="fit the steering loop's PI gains (Adam through the closed-loop run; "
                                           "GM ≥ 6 dB, PM ≥ 45°) beside SIMC and Ziegler–Nichols")
    p.add_argument("scene", nargs="?", default="two-roller-steered", help=SCENE_HELP)
    p.add_argument("--objective", choices=tuple(OBJECTIVES), default="ise",
                   help="ise: ∫ e² dt (µm²·s); peak: soft max |e| (µm); e the sensor error")
    p.add_argument("--iterations", type=int, default=40, help="Adam iterations (default 40)")
    p.add_argument("--t-end", type=float, default=None, help="length of each closed-loop run, s (default: the scene's)")
    p.add_argument("--json", action="store_true", help="the report as JSON")
    p.set_defaults(func=run)
    return p


def run(args):
    check_at_least("--iterations", args.iterations, 0)
    scene, _, model, options = load_run(args.scene, t_end=args.t_end)
    if not scene.control:
        raise UsageError(f"scene {scene.name!r} has no steering loop ([[control]] table)")
    if len(scene.control) != 1:
        raise UsageError(f"scene {scene.name!r} has {len(scene.control)} steering loops; tune handles one")
    if options.t_end <= 0.5:
        raise UsageError(f"--t-end = {options.t_end:g}: must be longer than the 0.5 s start window")
    result = tune(model, options, kind=args.objective, iterations=args.iterations, scene_name=scene.name,
                  progress=not args.json)
    emit(args, result.to_dict(), _print)
    return 0


def _print(r):
    p = r["plant"]
    print(f"{r['scene']}: loop {r['loop']}, objective {r['objective']} over {r['skip_s']:g}–{r['t_end_s']:g} s "
          f"({r['objective_unit']}), GM ≥ {r['gm_min_db']:g} dB, PM ≥ {r['pm_min_deg']:g}°")
    recirculation = p.get("loop_delay", 0.0) + 2 * p.get("loop_lag", 0.0)
    print(f"plant: k = {p['gain']:.4g} mm/s per mrad, τ = {p['lag']:.3g} s, θ = {p['delay']:.3g} s, "
          f"recirculation {recirculation:.3g} s ({r['plant_source']}); measured walk rate {r['response_rate']:.4g} "
          "mm/s per mrad")
    print(r["start_note"])
    print(f"{'gains':16s} {'kp':>8s} {'ki':>8s} {'objective':>11s} {'peak µm':>8s} {'GM dB':>7s} {'PM °':>6s} "
          f"{'GM* dB':>7s} {'PM* °':>6s}  ok")
    for q in [r["start"], r["tuned"], *r["classical"]]:
        print(f"{q['rule']:16s} {q['kp_mrad_per_mm']:8.4g} {q['ki_mrad_per_mm_s']:8.4g} {fmt(q['objective']):>11s} "
              f"{fmt(q['peak_um']):>8s} {fmt(q['gain_margin_db']):>7s} {fmt(q['phase_margin_deg']):>6s} "
              f"{fmt(q['response_gain_margin_db']):>7s} {fmt(q['response_phase_margin_deg']):>6s}  "
              f"{'yes' if q['feasible'] else 'no'}")
    print(f"kp mrad/mm, ki mrad/(mm s); GM/PM on the identified plant, GM*/PM* on the measured response; "
          f"objective {r['improvement'] * 100:.1f} % below the start after {r['iterations']} iterations "
          f"({r['wall_s']:.1f} s)")
