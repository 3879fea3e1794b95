"""The built-in design scenes' grids against the 5 % rule: the metric's discretisation error at the
tolerance box's worst corners, one grid level finer, as a share of the limit.

Runs ``jaxbelt tolerance SCENE --json`` (error bars on) on ``three-roller-steered`` (the default:
lateral and longitudinal ≤ 20 µm and the actuator within its range over 16–20 s) and on the
source's variant ``three-roller-tolerance`` (lateral_max ≤ 20 µm at 4 s), and records the worst
corner on the scene's grid and on the grid one level finer (elements ×2 along and across,
Δt / 2), the change as a share of the limit (the rule: ≤ 5 %), and the half-widths' relative
change. Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/design_error_bars.py``. Writes
``results/design_error_bars.json``.
"""

import contextlib
import io
import json
import time

from _common import write

from jaxbelt.cli import main as cli

SCENES = ("three-roller-steered", "three-roller-tolerance")
LIMIT_UM = 20.0


def main():
    rows = []
    for scene in SCENES:
        t0 = time.perf_counter()
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            assert cli(["tolerance", scene, "--limit-um", str(LIMIT_UM), "--json"]) == 0
        r = json.loads(buf.getvalue())
        d = r["discretisation"]
        row = dict(scene=scene, limit_um=LIMIT_UM, binding_limit=r["binding_limit"], grid=d["grid"],
                   grid_fine=d["grid_fine"], worst_case_um=d["worst_case_um"], worst_case_fine_um=d["worst_case_fine_um"],
                   metric_change_share_of_limit=abs(d["worst_case_fine_um"] - d["worst_case_um"]) / LIMIT_UM,
                   half_width_relative_change=d["half_width_relative_change"], wall_s=time.perf_counter() - t0)
        row["meets_5_percent_rule"] = row["metric_change_share_of_limit"] <= 0.05
        rows.append(row)
        print(f"{scene}: worst corner {d['worst_case_um']:.4g} µm, one level finer {d['worst_case_fine_um']:.4g} µm: "
              f"{100 * row['metric_change_share_of_limit']:.2f} % of the limit; half-widths "
              f"{100 * d['half_width_relative_change']:+.2f} % ({row['wall_s']:.0f} s)", flush=True)
    write("design_error_bars", {"rows": rows})


if __name__ == "__main__":
    main()
