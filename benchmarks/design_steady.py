"""The README's answer: the main job as a user runs it, its output kept.

Runs ``jaxbelt tolerance --json`` (the default scene ``three-roller-steered``, judged in steady
operation, error bars on) and ``jaxbelt tolerance three-roller-tolerance --json`` (the source's
variant), each in-process through :func:`jaxbelt.cli.main`, and keeps both JSON outputs with their
wall times. ``scripts/readme_results.py`` writes the README's table and figures from this file.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/design_steady.py``. Writes
``results/design_steady.json``.
"""

import contextlib
import io
import json
import time

from _common import write

import jaxbelt as jb
from jaxbelt.cli import main as cli


def run(argv):
    buf = io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(buf):
        rc = cli(argv)
    if rc != 0:
        raise SystemExit(f"jaxbelt {' '.join(argv)}: exit code {rc}")
    return json.loads(buf.getvalue()), time.perf_counter() - t0


def main():
    loops = jb.build_model(jb.load_scene("three-roller-steered")).control
    roller, axis = loops.labels[0].rsplit("/", 1)
    steered, t_steered = run(["tolerance", "--json"])
    source, t_source = run(["tolerance", "three-roller-tolerance", "--json"])
    write("design_steady", {
        "three-roller-steered": steered, "three-roller-tolerance": source,
        "actuated_component": f"{roller}:a{axis}",
        "command_s": {"three-roller-steered": t_steered, "three-roller-tolerance": t_source},
    })


if __name__ == "__main__":
    main()
