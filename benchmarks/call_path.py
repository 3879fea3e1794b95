"""How a sweep's study travels through the design package: the module stops of ``jaxbelt sweep``.

Runs ``jaxbelt sweep`` in-process on a small scene (the three-roller machine with two element rows,
24 Monte-Carlo samples, FORM and the error bar as by default) under a profiler that records every Python call into a module of
``jaxbelt.design`` (tracing included: it is the code a reader follows). Consecutive calls within
one module are one *stop*; a stop in a module the path had already left is a *return*. Writes
``results/call_path.json``: the stops in order, their count, the modules entered, the returns,
and the stops per module.

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/call_path.py``.
"""

import collections
import contextlib
import io
import sys
import tempfile
from pathlib import Path

from _common import write

from jaxbelt.cli import main as cli

SMALL = """extends = "three-roller-tolerance"
[mesh]
n_eta = 2
[time]
t_end_s = 0.24
"""
DIST = """[roller."roller 2"]
rotation_mrad = {dist = "normal", sigma = [0.05, 0.05, 0.0]}
"""
PACKAGE = "jaxbelt.design"


def main():
    stops = []

    def profile(frame, event, arg):
        if event != "call":
            return
        module = frame.f_globals.get("__name__", "")
        if module.startswith(PACKAGE) and (not stops or stops[-1] != module):
            stops.append(module)

    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        (d / "small.toml").write_text(SMALL)
        (d / "dist.toml").write_text(DIST)
        argv = ["sweep", str(d / "small.toml"), "--dist", str(d / "dist.toml"), "--samples", "24",
                "--solver", "reuse", "--json"]
        sys.setprofile(profile)
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                rc = cli(argv)
        finally:
            sys.setprofile(None)
    if rc != 0:
        raise SystemExit(f"jaxbelt {' '.join(argv)}: exit code {rc}")
    seen, returns = set(), 0
    for i, m in enumerate(stops):
        returns += m in seen
        seen.add(m)
    write("call_path", {"command": "jaxbelt sweep SMALL --dist DIST --samples 24 --solver reuse",
                        "stops": len(stops), "modules": len(seen), "returns_to_a_module_left": returns,
                        "stops_per_module": dict(collections.Counter(stops).most_common()), "path": stops})
    print(f"{len(stops)} stops in {len(seen)} modules, {returns} returns")


if __name__ == "__main__":
    main()
