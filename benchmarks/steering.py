"""The steering plant against its references (``docs/steering.md``): the steering coefficient's grid
convergence to the moving-beam theory on ``two-roller-steered``, the plant report, the P loop's
stability boundary from closed-loop runs against the gain margins, the PI loop holding the belt,
the string limit against Shelton's first-order span model, and the design scene's coefficient.

Run: ``python benchmarks/steering.py [--no-three-roller]``. Writes ``results/steering.json``.
"""

import argparse
import time

import jax.numpy as jnp
import numpy as np

import jaxbelt as jb
from _common import write
from jaxbelt import lateral_theory as th
from jaxbelt.steering import margins, stability_boundary, steering_report, walk_rate
from jaxbelt.steering.response import response_transfer
from jaxbelt.run_checks import belt_speed

BASE = "two-roller-steered"
GRIDS = [(6, 8), (12, 16), (24, 32), (48, 64), (96, 128), (6, 16), (6, 32), (24, 8)]


def _skew(p=2, roller=1, alpha=1e-3):
    a = np.zeros((p, 3))
    a[roller, 1] = alpha
    return a


def convergence():
    """Walk of the idle roller's 1 mrad skew (loop open) against the Timoshenko loop, per grid."""
    rows = []
    for ne, nf in GRIDS:
        sc0 = jb.load_scene(BASE)
        ell = min(np.pi * 0.05 / ne, 0.275 / nf)
        dt = min(0.02, 0.8 * ell / 0.5)
        n = int(round(12.0 / dt))
        sc = jb.scene_from_dict({"extends": BASE, "mesh": {"roller_elements": [ne, ne], "free_elements": [nf, nf]},
                                 "time": {"dt_s": dt, "t_end_s": n * dt}})
        m = jb.build_model(sc)
        m = jb.with_misalignment(m.replace(control=m.control.with_gains(0.0, 0.0, 0.0)), rotation=jnp.asarray(_skew()))
        t0 = time.perf_counter()
        _, tr = jb.simulate(m, **jb.RunOptions.from_scene(sc))
        t = np.asarray(tr.t)
        c = float(walk_rate(t, np.asarray(tr.tracer_v).mean(axis=1), (t[-1] / 2, t[-1])))
        cs = float(walk_rate(t, np.asarray(tr.sensor_v[:, 0]), (t[-1] / 2, t[-1])))
        ref = th.scene_walk_rate(sc0, _skew())
        rows.append(dict(roller_elements=ne, free_elements=nf, dt_s=dt, t_end_s=n * dt, walk_mm_s=c * 1e3,
                         sensor_walk_mm_s=cs * 1e3, theory_mm_s=ref * 1e3, deviation=c / ref - 1,
                         sensor_deviation=cs / ref - 1, elapsed_s=time.perf_counter() - t0))
        print(f"{ne}/{nf} dt {dt:.4g}: {100 * (c / ref - 1):+.2f} % (sensor {100 * (cs / ref - 1):+.2f} %)")
    return rows


def plant_and_loops():
    sc = jb.load_scene(BASE)
    m, o = jb.build_model(sc), jb.RunOptions.from_scene(sc)
    out = {}
    for n in (600, 2000):
        r = steering_report(m, o.replace(n_steps=n), sensitivity=False)
        d = r.to_dict()
        d.pop("step_response")
        d["plant_gain_margin_without_hold"] = margins(r.plant, 1.0)[0]
        out[f"report_{n}_steps"] = d
        print(f"report {n}: k {r.coefficient_mm_s_per_mrad:.5g}, hold {r.hold_angle_mrad:.5g}, GM response "
              f"{r.response_gain_margin:.4g}, plant {r.plant_gain_margin:.4g} (no hold {d['plant_gain_margin_without_hold']:.4g})")
    b = stability_boundary(m, o.replace(n_steps=2000), 2.5, 4.0, rounds=4, batch=3)
    out["boundary"] = b.to_dict()
    kp = b.kp_mrad_per_mm
    for n in (600, 2000):
        d = out[f"report_{n}_steps"]
        d["deviation_from_boundary"] = {k: d[k] / kp - 1 for k in ("response_gain_margin", "plant_gain_margin",
                                                                     "plant_gain_margin_without_hold")}
    print(f"boundary {b.bracket}")
    _, tr = jb.simulate(m, **o.replace(n_steps=7500))
    t, v, u = np.asarray(tr.t), np.asarray(tr.sensor_v[:, 0]), np.asarray(tr.control_u[:, 0])
    hold = out["report_2000_steps"]["hold_angle_mrad"]
    settle = [float(t[i]) for i in range(len(t)) if np.max(np.abs(v[i:])) < 0.1e-6][:1]
    out["pi_loop"] = dict(t_end_s=float(t[-1]), kp_mrad_per_mm=float(m.control.kp[0]),
                          ki_mrad_per_mm_s=float(m.control.ki[0]), max_error_um_after_110_s=float(np.max(np.abs(v[t >= 110])) * 1e6),
                          error_um_at_40_s=float(v[np.argmin(np.abs(t - 40))] * 1e6),
                          below_0_1_um_from_s=settle[0] if settle else None, final_angle_mrad=float(u[-1] * 1e3),
                          hold_angle_mrad=hold, angle_deviation=float(u[-1] * 1e3 / hold - 1))
    print(out["pi_loop"])
    return out


def string_limit():
    rows = []
    for w_mm, ne, nf, dt in ((5.0, 6, 8, 0.02), (2.5, 24, 32, 0.0125)):
        sc = jb.scene_from_dict({"extends": BASE, "belt": {"width_mm": w_mm, "length_mm": 855.6},
                                 "mesh": {"roller_elements": [ne, ne], "free_elements": [nf, nf]},
                                 "time": {"dt_s": dt, "t_end_s": 12.0},
                                 "control": [{"actuator": "idle", "axis": "y", "sensor_mm": [689.0, w_mm / 2],
                                              "kp_mrad_per_mm": 0.0}]})
        m = jb.build_model(sc)
        r = steering_report(m, jb.RunOptions.from_scene(sc), sensitivity=False)
        geom, length = th.scene_geometry(sc)
        b = sc.belt
        EI, _ = th.belt_section(b.width, b.thickness, b.youngs_modulus, b.poisson_ratio)
        kl = float(geom.span_length[0] * np.sqrt(b.youngs_modulus * b.pre_strain(length) * b.area / EI))
        frac = np.round(np.arange(0.05, 1.51, 0.05), 2)
        w = frac * 2 * np.pi / r.loop_time_s
        G = th.string_loop_response(sc, w)
        meas = response_transfer(r.step_response.sensor_um_per_mrad * 1e-3, r.coefficient_mm_s_per_mrad, dt, w) \
            * np.exp(0.5j * w * dt)
        fit = r.plant.frequency_response(w)
        row = dict(width_mm=w_mm, K_L=kl, grid=[ne, nf], dt_s=dt, coefficient_mm_s_per_mrad=r.coefficient_mm_s_per_mrad,
                   string_mm_s_per_mrad=float((1j * w[0] * G[0]).real), theory_mm_s_per_mrad=th.scene_walk_rate(sc, _skew()) * 1e3,
                   frequency_over_transit=frac.tolist(), response_deviation=np.abs(meas / G - 1).tolist(),
                   plant_deviation=np.abs(fit / G - 1).tolist(), plant=r.plant)
        rows.append(row)
        print(f"K L {kl:.3g}: k {row['coefficient_mm_s_per_mrad']:.4g} string {row['string_mm_s_per_mrad']:.4g} "
              f"theory {row['theory_mm_s_per_mrad']:.4g}; response dev at 0.5 {row['response_deviation'][9]:.3f}")
    return rows


def three_roller():
    sc = jb.load_scene("three-roller-steered")
    m, o = jb.build_model(sc), jb.RunOptions.from_scene(sc)
    t0 = time.perf_counter()
    r = steering_report(m, o, sensitivity=False, identify=False)
    ref = th.scene_walk_rate(sc, _skew(3)) * 1e3
    mm = jb.with_misalignment(m.replace(control=m.control.with_gains(0.0, 0.0, 0.0)), rotation=jnp.asarray(_skew(3)))
    _, tr = jb.simulate(mm, **o)
    t = np.asarray(tr.t)
    c = float(walk_rate(t, np.asarray(tr.tracer_v).mean(axis=1), (t[-1] / 2, t[-1]))) * 1e3
    out = dict(coefficient_mm_s_per_mrad=r.coefficient_mm_s_per_mrad, tracer_walk_mm_s_per_mrad=c,
               theory_mm_s_per_mrad=ref, deviation=r.coefficient_mm_s_per_mrad / ref - 1, tracer_deviation=c / ref - 1,
               hold_angle_mrad=r.hold_angle_mrad, loop_time_s=r.loop_time_s, belt_speed_m_s=belt_speed(m),
               elapsed_s=time.perf_counter() - t0)
    print(out)
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--no-three-roller", action="store_true")
    args = ap.parse_args()
    out = {"scene": BASE, "convergence": convergence(), **plant_and_loops(), "string_limit": string_limit()}
    if not args.no_three_roller:
        out["three_roller_steered"] = three_roller()
    write("steering", out)


if __name__ == "__main__":
    main()
