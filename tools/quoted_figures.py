"""Check that the figures the docs quote are the ones docs/RESULTS.md shows.

A doc quotes a measured figure in a paragraph or list item that names its source,
``(docs/RESULTS.md: SECTION[, SECTION ...])``, SECTION being a ``<!-- BEGIN SECTION -->``
name of the results file. Every decimal number of that paragraph (outside `code`
spans and the reference itself) must be a number the named sections show, rounded
to the digits quoted (``0.058`` matches ``0.0582``; ``24.6 %`` matches ``24.6``).
Integers are not checked (counts such as "17 of 25" are read from a table, and
"Eq. 10" is not a figure).

A doc's results section (:data:`RESULTS_HEADINGS`: the README's "Results in one glance") quotes
nothing else: each of its paragraphs and list items with a decimal number must name its sections.

Run after ``make results`` to see which quotes the new figures changed::

    python tools/quoted_figures.py            # README.md and docs/PAPER.md against docs/RESULTS.md

Exit status 1 with one line per figure that the named sections do not show.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = (ROOT / "README.md", ROOT / "docs" / "PAPER.md")
RESULTS = ROOT / "docs" / "RESULTS.md"
RESULTS_HEADINGS = {"README.md": "## Results in one glance"}  # a section of measured figures only: every one cited

REFERENCE = re.compile(r"\(docs/RESULTS\.md:\s+([^)]+)\)")  # the reference may break across lines
NUMBER = re.compile(r"(?<![\w.])-?\d+\.\d+(?![\w.]*\d)")  # a decimal number, not part of a version or a name
CODE = re.compile(r"`[^`]*`")


def sections(text: str) -> dict[str, str]:
    """``{name: body}`` of every ``<!-- BEGIN name -->`` ... ``<!-- END name -->`` section."""
    return {m.group(1): m.group(2) for m in re.finditer(r"<!-- BEGIN (\S+) -->(.*?)<!-- END \1 -->", text, re.S)}


def blocks(text: str) -> list[tuple[int, str]]:
    """Paragraphs and list items with their first line number (a list item ends at the next item or a blank line)."""
    out, current, start = [], [], 0
    for i, line in enumerate(text.splitlines(), 1):
        item = re.match(r"\s*([-*]|\d+\.)\s", line) is not None
        if not line.strip() or (item and current):
            if current:
                out.append((start, "\n".join(current)))
            current = []
        if line.strip():
            if not current:
                start = i
            current.append(line)
    if current:
        out.append((start, "\n".join(current)))
    return out


def _shown(value: str, numbers: list[float]) -> bool:
    digits = len(value.split(".")[1])
    q = float(value)
    return any(abs(abs(r) - abs(q)) <= 0.5 * 10**-digits + 1e-12 for r in numbers)


def _results_lines(doc: Path, text: str) -> range:
    """The line numbers of ``doc``'s results section (:data:`RESULTS_HEADINGS`; empty if it has none)."""
    heading = RESULTS_HEADINGS.get(doc.name)
    lines = text.splitlines()
    if heading is None or heading not in lines:
        return range(0)
    start = lines.index(heading) + 1
    end = next((i for i in range(start, len(lines)) if lines[i].startswith("## ")), len(lines))
    return range(start + 1, end + 1)


def check(doc: Path, results: Path = RESULTS) -> list[str]:
    """One message per quoted figure of ``doc`` that its named sections do not show (and per unknown section),
    and per figure of its results section without a source."""
    known = sections(results.read_text())
    text = doc.read_text()
    in_results = _results_lines(doc, text)
    problems = []
    for line, block in blocks(text):
        block = CODE.sub("", block)  # `code` is neither a figure nor a reference
        refs = REFERENCE.findall(block)
        if not refs:
            if line in in_results and NUMBER.search(block):
                problems.append(f"{doc.name}:{line}: {NUMBER.search(block).group()} has no source (docs/RESULTS.md: SECTION)")
            continue
        names = [n.strip() for ref in refs for n in ref.split(",") if n.strip()]
        missing = [n for n in names if n not in known]
        if missing:
            problems.append(f"{doc.name}:{line}: no section {', '.join(missing)} in {results.name}")
            continue
        numbers = [float(x) for n in names for x in NUMBER.findall(known[n])]
        text = REFERENCE.sub("", block)
        for value in NUMBER.findall(text):
            if not _shown(value, numbers):
                problems.append(f"{doc.name}:{line}: {value} is not shown in {', '.join(names)}")
    return problems


def main(argv: list[str] | None = None) -> int:
    docs = [Path(a) for a in (argv if argv is not None else sys.argv[1:])] or list(DOCS)
    problems = [p for doc in docs for p in check(doc)]
    for p in problems:
        print(p)
    if not problems:
        print(f"quoted figures: every figure of {', '.join(d.name for d in docs)} is shown in {RESULTS.name}")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
