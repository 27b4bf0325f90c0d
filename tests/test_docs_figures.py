"""Every measured figure in the README and docs/*.md comes from a committed result.

(a) ``scripts/gen_bench_docs.py --check``: ``docs/benchmarks.md`` and the README's
summary block are what the committed ``docs/bench/*.json`` give.

(b) The prose of ``README.md`` and ``docs/*.md`` (outside fenced code, inline code and
generated blocks, and not ``docs/benchmarks.md``, which is generated whole) is scanned
for measured-figure patterns: a number followed by a time or ratio unit (``s``, ``ms``,
``µs``, ``seconds``, ``x``, ``×``, ``times``) or a percentage. Each must be a measured
value of a row of a committed ``docs/bench/*.json``, or be one of the few definitions
in :data:`ALLOWED` (a parameter, a threshold, a formula's value), not a measurement.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SCRIPT = ROOT / "scripts" / "gen_bench_docs.py"

#: A number, then a time or ratio unit or a percent sign; not a dimension such as
#: "1000 x 1000" (a number right after the x).
FIGURE = re.compile(
    r"(?<![\w.])(?P<num>\d[\d,]*(?:\.\d+)?)\s?(?P<unit>ms|µs|μs|seconds|s|x|×|times|%)"
    r"(?!\w)(?!\s?\d)")

#: Figures that are definitions, not measurements: (pattern, why). A figure is allowed
#: when a match of the pattern on its line covers it.
ALLOWED = (
    # kept fractions: inputs of the reduction (the paper's Figure 9 keeps 17.6%, Figure 11
    # reduces to 15%, the benchmark also keeps 42%, the error curves 10% to 60%)
    (r"17\.6%", "the kept fraction of the paper's Figure 9, an input"),
    (r"42%", "the benchmark's second kept fraction, an input"),
    (r"at (?:10|30)%|reduced to 10%", "kept fractions of the error curves, inputs"),
    (r"(?:to|reduced to) 15%|down to 15%", "the level of the paper's Figure 11, an input"),
    (r"reduced to 25%", "the fraction the demo refines from, an input"),
    (r"50% reduction", "the fraction of the Figure 12 cycles, an input"),
    (r"the 10% of (?:input )?points of highest curvature",
     "the feature region's definition (bench reduce)"),
    # thresholds: the DoubtfulMeshWarning's and the tests' assertions
    (r"more than 1% (?:of the|judged)", "a DoubtfulMeshWarning threshold (core/mesh.py)"),
    (r"within 1% of the edge|never more than 1% of the radius|at most 1% of the diagonal"
     r"|volume within 2%", "a threshold asserted by tests/test_refinement.py"),
    (r"exceed 1\.6 times", "a threshold asserted by tests/test_vdfc.py"),
    (r"at most 1\.1 times|1\.05 times at 200,000",
     "the thresholds asserted by tests/test_distributed.py (blocked reduction)"),
    # the paper's own figure, quoted as the paper's
    (r"that 0\.01% of the result", "the paper's statement, not our measurement"),
    # algorithm constants, geometry, a formula and test inputs
    (r"at 1, 2 and 4 times", "the void search's distances (core/fans.py)"),
    (r"at most 3 times", "the curvature move's iteration limit (core/refinement.py)"),
    (r"over 5× the median", "the criterion of a bridging ring edge"),
    (r"about 1\.4 times\s+farther|about 1\.4 times$", "sqrt(2): a half plane's geometry"),
    (r"10x density|10x along", "the density ramp of a test input and of the corpus"),
    (r"2% pixels", "the simulated scan's dropout, an input of the corpus"),
    (r"97% of the first attempts", "the formula's value 0.975 just above it"),
)

#: Files whose every line is generated.
GENERATED_FILES = ("docs/benchmarks.md",)


def measured_values() -> set[str]:
    """The ``measured`` value of every row of every committed result, as plain numbers."""
    values = set()
    for path in sorted((ROOT / "docs" / "bench").glob("*.json")):
        for row in json.loads(path.read_text(encoding="utf-8")).get("rows", []):
            for num in re.findall(r"\d[\d,]*(?:\.\d+)?", str(row.get("measured", ""))):
                values.add(num.replace(",", ""))
    return values


def prose_lines(text: str):
    """(line number, line) outside fenced code and generated blocks; inline code blanked."""
    fenced = generated = False
    for i, line in enumerate(text.splitlines(), 1):
        stripped = line.strip()
        if stripped.startswith(("```", "~~~")):
            fenced = not fenced
            continue
        if stripped.startswith("<!-- BEGIN"):
            generated = True
            continue
        if stripped.startswith("<!-- END"):
            generated = False
            continue
        if fenced or generated:
            continue
        yield i, re.sub(r"`[^`]*`", lambda m: " " * len(m.group()), line)


def unsourced(text: str, values: set[str]) -> list[tuple[int, str]]:
    """(line number, figure) of every figure neither measured nor allowed."""
    out = []
    for i, line in prose_lines(text):
        allowed = [m.span() for pattern, _ in ALLOWED for m in re.finditer(pattern, line)]
        for m in FIGURE.finditer(line):
            if m.group("num").replace(",", "") in values:
                continue
            if any(a <= m.start() and m.end() <= b for a, b in allowed):
                continue
            out.append((i, m.group()))
    return out


def doc_files() -> list[Path]:
    files = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    return [p for p in files if p.relative_to(ROOT).as_posix() not in GENERATED_FILES]


def test_generated_bench_docs_are_up_to_date():
    run = subprocess.run([sys.executable, str(SCRIPT), "--check"], capture_output=True,
                         text=True, cwd=ROOT, check=False)
    assert run.returncode == 0, run.stdout + run.stderr


def test_every_quoted_figure_is_in_a_committed_result():
    values = measured_values()
    assert values, "no committed result in docs/bench/"
    bad = [f"{path.relative_to(ROOT)}:{i}: {figure!r}"
           for path in doc_files()
           for i, figure in unsourced(path.read_text(encoding="utf-8"), values)]
    assert not bad, ("figures not found among the measured values of docs/bench/*.json "
                     "(point to docs/benchmarks.md instead, or allow a definition in "
                     "ALLOWED):\n" + "\n".join(bad))


def test_the_scan_finds_an_unsourced_figure():
    values = {"1.249"}
    text = "\n".join([
        "Building takes 0.31 s on the bunny and is 2.5x faster; 12% of fans open.",
        "Quoted from the result: 1.249 x (mesh_speed).",
        "Reduced to 17.6% (an input); a grid of 1000 x 1000 points.",
        "```", "timing = 9.9 s  # code, not prose", "```",
        "<!-- BEGIN X -->", "7.7 ms generated", "<!-- END X -->",
        "Inline `--timeout 600 s` is code.",
    ])
    assert [fig for _, fig in unsourced(text, values)] == ["0.31 s", "2.5x", "12%"]
