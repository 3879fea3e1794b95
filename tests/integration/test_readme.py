"""The README is the front door: its first Python example runs as pasted (the quick start a fresh
install meets), it stays short, it opens with the two set-up commands, and neither it nor the docs
pages talk about how the project was developed or point outside the repository."""

import re

import pytest
from helpers import REPO

ROOT = REPO
README = ROOT / "README.md"
MAX_README_LINES = 250


def first_block(text: str, lang: str) -> str:
    m = re.search(rf"^```{lang}\n(.*?)^```", text, re.S | re.M)
    assert m, f"README.md has no ```{lang} block"
    return m.group(1)


def first_python_block(text: str) -> str:
    return first_block(text, "python")


def test_readme_first_python_example_runs():
    code = first_python_block(README.read_text())
    assert "jb.simulate" in code  # the API quick start, not some other snippet
    namespace = {"__name__": "__readme__"}
    exec(compile(code, str(README), "exec"), namespace)
    traj = namespace["traj"]
    assert traj.tracer_u.shape[0] > 0 and bool((abs(traj.tracer_u) < 1.0).all())


def test_readme_is_short_and_opens_with_the_two_setup_commands():
    text = README.read_text()
    lines = text.splitlines()
    assert len(lines) <= MAX_README_LINES, f"README.md has {len(lines)} lines (at most {MAX_README_LINES})"
    assert lines[0] == "# jaxbelt"
    assert text.find("```bash") < text.find("```python"), "the set-up block comes before the Python example"
    commands = [ln for ln in first_block(text, "bash").splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    assert len(commands) == 2, commands
    assert all(c.startswith('pip install -e ".[dev]" && ') for c in commands)
    assert "jaxbelt tolerance" in commands[0] and "python -m pytest -q" in commands[1]


# Development talk and pointers outside the repository, each pattern narrow enough to hit only the
# real thing (see test_front_door_patterns_hit_only_the_real_thing).
FORBIDDEN = {
    "a path outside the repository": re.compile(r"\.\./shared\b"),
    "a reference to the specification's file instead of docs/model.md": re.compile(r"\bMODEL\.md\b"),
    "session talk": re.compile(r"\bsessions?\b", re.I),
    "issue talk": re.compile(r"\bissues?\s*(?:#\s*)?\d|\bissue\s+goals?\b", re.I),
    # 7-40 hex digits with at least one digit and one letter a-f (so no plain number and no word),
    # not inside a longer word or number, a colour (#...) or a 0x literal; "_" may border it (file names)
    "a commit hash": re.compile(r"(?<![0-9A-Za-z#.])(?=[0-9a-f]*[0-9])(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}(?![0-9A-Za-z])"),
    "a commit named by an all-digit hash": re.compile(r"\bcommits?\s+[0-9a-f]{7,40}\b", re.I),
}


def front_door_files():
    return [README, *sorted((ROOT / "docs").rglob("*.md"))]


def violations(text: str):
    found = []
    for what, pattern in FORBIDDEN.items():
        for m in pattern.finditer(text):
            line = text.count("\n", 0, m.start()) + 1
            found.append(f"line {line}: {what}: {m.group(0)!r}")
    return found


@pytest.mark.parametrize("path", front_door_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_front_door_speaks_of_the_product(path):
    assert not violations(path.read_text()), "\n".join(violations(path.read_text()))


@pytest.mark.parametrize("text", [
    "see ../shared/design/MODEL.md", "as MODEL.md §3 fixes", "this session's run", "Sessions 5 and 7",
    "issue #5", "issue 12 asked", "the issue goal of 2.5 s", "measured at a7e3c49", "commit 4333636",
    "step_vs_superlu_598e671.json", "git bisect found d6db02d5f0c1e2a3b4c5d6e7f8a9b0c1d2e3f4a5",
])
def test_front_door_patterns_hit_the_real_thing(text):
    assert violations(text), text


@pytest.mark.parametrize("text", [
    "a strain of 0.0021851 at 5 ms", "N = 3762, 1000000 steps", "1.5e-10 mm", "the issue is that",
    "colour #1f77b4ff", "0xdeadbeef1", "decaded effaced", "docs/model.md §3", "a Jupyter kernel",
    "float32 and float64", "1e-13 relative", "three-roller-t73-test1", "sha256 checksums",
])
def test_front_door_patterns_leave_ordinary_text_alone(text):
    assert not violations(text), violations(text)


def test_readme_results_are_what_the_script_writes_from_the_benchmark():
    """The 20 µm table and every figure around it are ``scripts/readme_results.py``'s rendering of
    ``benchmarks/results/design_steady.json`` (the main job's own output), so they cannot drift."""
    import importlib.util
    spec = importlib.util.spec_from_file_location("readme_results", README.parent / "scripts" / "readme_results.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    for (path, begin, end), new in mod.expected().items():
        assert mod.block(path.read_text(), begin, end) == new, path
    rows = [ln for ln in mod.block(README.read_text()).splitlines() if re.match(r"\| roller \d", ln)]
    assert len(rows) == 3
