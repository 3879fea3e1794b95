"""``jaxbelt bench [--quick] [--only baselines|pareto] [--out DIR]``: the measured speed/accuracy
trade and the baselines (:mod:`jaxbelt.bench`), written as JSON, PNG and a Markdown table."""

from __future__ import annotations

import os
from pathlib import Path

from ._common import UsageError


def add_parser(subparsers):
    p = subparsers.add_parser("bench", help="measure speed against SciPy SuperLU and the speed/accuracy trade")
    p.add_argument("--quick", action="store_true",
                   help="small rounds, a 4 s horizon and fewer candidates (≈ 5 min on 2 cores)")
    p.add_argument("--only", choices=("baselines", "pareto"), default=None, help="one part only")
    p.add_argument("--out", default=None,
                   help="output directory (default: benchmarks/results when run in a jaxbelt checkout, else ./jaxbelt-bench)")
    p.set_defaults(func=run)
    return p


def run(args):
    try:
        import scipy  # noqa: F401
    except ImportError as e:  # the SuperLU baseline is a reference, not a dependency of the package
        raise UsageError("jaxbelt bench needs SciPy for its SuperLU baseline: pip install scipy") from e
    out = Path(args.out) if args.out else (Path("benchmarks/results") if Path("benchmarks").is_dir()
                                         and Path("jaxbelt").is_dir() else Path("jaxbelt-bench"))
    if out.exists() and not out.is_dir():
        raise UsageError(f"--out {out}: exists and is not a directory")
    if os.environ.get("OPENBLAS_NUM_THREADS") is None:
        import sys

        print("jaxbelt: note: OPENBLAS_NUM_THREADS is not set; on a shared machine set it to 1 for "
              "steadier SuperLU figures", file=sys.stderr)
    from ..bench import run_all

    parts = (args.only,) if args.only else ("baselines", "pareto")
    results = run_all(out, quick=args.quick, parts=parts)
    if "baselines" in results:
        b = results["baselines"]
        print(f"per step on {b['scene']} (N = {b['n_unknowns']}), ms:")
        for k, v in b["per_step"]["ms_per_step"].items():
            print(f"  {k:45s} {v:9.3f}")
        for k, v in b["per_step"]["ratios"].items():
            print(f"  {k:65s} {v:6.2f}")
        w = b["whole_run_reuse"]
        print(f"whole {w['t_end_s']:g} s run (reuse): {w['run_s']:.2f} s; compile cold "
              f"{b['compilation']['cold']['by_steps']['5000']['compile_s']:.2f} s, second process "
              f"{b['compilation']['warm']['by_steps']['5000']['compile_s']:.2f} s")
    if "pareto" in results:
        from ..bench.pareto import table_markdown

        print(table_markdown(results["pareto"]))
    print(f"results in {out}/")
    return 0
