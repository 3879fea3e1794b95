"""The whole 100 s reuse run of ``three-roller-t72`` for two commits side by side: each commit's
tree checked out by ``git worktree`` into a temporary folder, the two timed in alternating fresh
processes (:func:`jaxbelt.bench.baselines.whole_run`, compile apart, best of 3 per process),
``--rounds`` rounds, best of each side kept. The machine's speed drifts by ×1.3–1.9 between
minutes; alternating processes put both sides through the same drift.
Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/whole_run_ab.py BEFORE [AFTER] [--rounds 4]``
(``AFTER`` defaults to the working tree). Writes ``results/whole_run_ab.json``.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from _common import write

ROOT = Path(__file__).resolve().parent.parent
CHILD = r"""
import json, sys
import jaxbelt as jb
from jaxbelt.bench.baselines import whole_run
r = whole_run(jb.load_model("three-roller-t72"), repeat=3)
print(json.dumps({"file": jb.__file__, **r}))
"""


def run_child(tree: Path) -> dict:
    env = {**os.environ, "PYTHONPATH": str(tree), "OPENBLAS_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, check=True,
                         cwd=tempfile.gettempdir())
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res["file"].startswith(str(tree)), res["file"]
    return res


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("before")
    ap.add_argument("after", nargs="?", default=None, help="a commit; default: the working tree")
    ap.add_argument("--rounds", type=int, default=4)
    a = ap.parse_args()
    sha = lambda ref: subprocess.run(["git", "rev-parse", "--short", ref], cwd=ROOT, capture_output=True,  # noqa: E731
                                     text=True, check=True).stdout.strip()
    with tempfile.TemporaryDirectory() as tmp:
        trees = {}
        for side, ref in (("before", a.before), ("after", a.after)):
            if ref is None:
                trees[side] = (ROOT, "working tree")
                continue
            path = Path(tmp) / side
            subprocess.run(["git", "worktree", "add", "--detach", str(path), ref], cwd=ROOT, check=True,
                           capture_output=True)
            trees[side] = (path, sha(ref))
        runs = {"before": [], "after": []}
        try:
            for k in range(a.rounds):
                for side in ("before", "after"):
                    r = run_child(trees[side][0])
                    runs[side].append(r["run_s"])
                    print(f"round {k + 1} {side:6s} {trees[side][1]:12s} {r['run_s']:.3f} s", flush=True)
        finally:
            for side, (path, _) in trees.items():
                if path != ROOT:
                    subprocess.run(["git", "worktree", "remove", "--force", str(path)], cwd=ROOT, capture_output=True)
    best = {s: min(v) for s, v in runs.items()}
    print(f"best: before {best['before']:.3f} s, after {best['after']:.3f} s, ratio {best['after'] / best['before']:.3f}")
    write("whole_run_ab", {"scene": "three-roller-t72", "n_steps": 5000,
                           "before": trees["before"][1], "after": trees["after"][1], "runs_s": runs, "best_s": best,
                           "after_over_before": best["after"] / best["before"]})


if __name__ == "__main__":
    main()
