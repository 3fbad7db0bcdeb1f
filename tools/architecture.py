"""The house as the code builds it: nlo_lab's stages, its import graph, and the picture in docs/ARCHITECTURE.md.

:data:`ORDER` is the one statement of the order the packages depend in (the data's path).
Everything else is read from the source with ast, nothing is imported: which nlo_lab modules
each module imports (inside functions too), the imports against the order, the circles. The
picture (a mermaid flowchart between the markers of docs/ARCHITECTURE.md) draws a box per
stage and an arrow where a stage imports another directly, leaving out
the spine (every package uses it) and the arrows implied by longer paths (transitive reduction).
``tests/packaging/test_dependencies.py`` holds the package to the order and the picture to the code.

Usage::

    python tools/architecture.py          # rewrite the picture in docs/ARCHITECTURE.md
    python tools/architecture.py --check  # exit 1 (and say so) if the picture is stale
    python tools/architecture.py --print  # the picture, and the figures: modules, largest, circles
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "nlo_lab"
DOC = ROOT / "docs" / "ARCHITECTURE.md"
BEGIN, END = "<!-- architecture.py: begin -->", "<!-- architecture.py: end -->"

# The stages, in the order the data flows and the imports go (docs/ARCHITECTURE.md, "The order").
# A module belongs to the last stage whose prefix it starts with; the root module nlo_lab alone
# is the front door, and nlo_lab/__main__.py (the program) is the command line's. The spine's modules each form a stage of their own, in the order they
# import each other.
SPINE = [
    "nlo_lab.errors",
    "nlo_lab.settings",
    "nlo_lab.files",
    "nlo_lab.npz_archive",
    "nlo_lab.atomic_files",
    "nlo_lab.threads",
    "nlo_lab.paths",
    "nlo_lab.rotations",
    "nlo_lab.graph",
]
ORDER = SPINE + [
    "nlo_lab.human",
    "nlo_lab.corpus",
    "nlo_lab.sources",
    "nlo_lab.robot",
    "nlo_lab.objective",
    "nlo_lab.model",
    "nlo_lab.inference",
    "nlo_lab.metrics",
    "nlo_lab.pipeline",
    "nlo_lab.training",
    "nlo_lab.evaluation",
    "nlo_lab.viz",
    "nlo_lab.lab",
    "nlo_lab.live",
    "nlo_lab.batch",
    "nlo_lab",  # the front door: nlo_lab/__init__.py
    "nlo_lab.cli",
]


def module_name(path: Path, package: Path = PACKAGE) -> str:
    parts = path.relative_to(package.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules(package: Path = PACKAGE) -> dict[str, Path]:
    """Every module of the package: dotted name -> file."""
    return {module_name(p, package): p for p in sorted(package.rglob("*.py"))}


def stage(module: str) -> int:
    """Index in :data:`ORDER`; -1 for a module no stage holds."""
    if module == "nlo_lab":
        return ORDER.index("nlo_lab")
    if module == "nlo_lab.__main__":  # the program (the console script, python -m nlo_lab): the command line's
        return ORDER.index("nlo_lab.cli")
    found = [i for i, prefix in enumerate(ORDER) if prefix != "nlo_lab" and (module == prefix or module.startswith(prefix + "."))]
    return found[-1] if found else -1


def _is_main_block(node: ast.stmt) -> bool:
    return isinstance(node, ast.If) and isinstance(node.test, ast.Compare) and getattr(node.test.left, "id", None) == "__name__"


def imports(path: Path, known: set[str], package: Path = PACKAGE) -> set[str]:
    """The nlo_lab modules ``path`` imports, anywhere in it (functions included, ``__main__`` blocks not).

    ``from pkg import sub`` where ``pkg.sub`` is a module imports that module; any other name
    imported from ``pkg`` is a dependency on ``pkg`` itself. The front door (the root module)
    imports the modules it names in strings (its ``__getattr__``). ``import nlo_lab`` for
    ``nlo_lab.__version__`` alone is no dependency on the front door: the root module runs
    before any module of the package, and its dunders need nothing.
    """
    module = module_name(path, package)
    parent = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    tree = ast.parse(path.read_text(encoding="utf-8"))
    main_blocks = {id(n) for block in tree.body if _is_main_block(block) for n in ast.walk(block)}
    found = set()
    for node in ast.walk(tree):
        if id(node) in main_blocks:
            continue
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(parent[: len(parent) - node.level + 1] + ([base] if base else []))
            found |= {f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names}
    if module == "nlo_lab":  # the front door names its homes as strings, imported on first use
        found |= {n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and n.value in known}
    root_uses = {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute) and getattr(n.value, "id", None) == "nlo_lab"}
    if all(attr.startswith("__") for attr in root_uses):
        found.discard("nlo_lab")
    return {m for m in found if m == "nlo_lab" or m.startswith("nlo_lab.")}


def import_graph(package: Path = PACKAGE) -> dict[str, set[str]]:
    """module -> the package's modules it imports (``__main__`` modules left out: programs, not dependencies)."""
    mods = modules(package)
    known = set(mods)
    return {m: (imports(p, known, package) & known) - {m} for m, p in mods.items() if not m.endswith("__main__")}


def backward_imports(package: Path = PACKAGE) -> list[tuple[str, str]]:
    """``(importer, imported)`` where the imported module belongs to a later stage than the importer."""
    graph = import_graph(package)
    return sorted((a, b) for a, targets in graph.items() for b in targets if stage(b) > stage(a))


def cycles(package: Path = PACKAGE) -> list[list[str]]:
    """Groups of modules that import each other in a circle (strongly connected components, Tarjan)."""
    graph = import_graph(package)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                out.append(sorted(group))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return sorted(out)


def _label(prefix: str) -> str:
    return "nlo_lab: the front door" if prefix == "nlo_lab" else prefix.removeprefix("nlo_lab.")


def diagram(package: Path = PACKAGE) -> str:
    """The mermaid flowchart of the stages after the spine (see the module docstring)."""
    graph = import_graph(package)
    first = len(SPINE)
    stages = ORDER[first:]
    direct = {(ORDER[stage(a)], ORDER[stage(b)]) for a, ts in graph.items() for b in ts if stage(a) >= first and stage(b) >= first}
    direct = {(a, b) for a, b in direct if a != b}
    reach = {s: {b for a, b in direct if a == s} for s in stages}
    for s in reversed(stages):  # stages only import earlier ones: reach the later closure first
        for t in list(reach[s]):
            reach[s] |= reach[t]
    reduced = sorted((a, b) for a, b in direct if not any(b in reach[c] for c in {y for x, y in direct if x == a} - {b}))
    spine = ", ".join(s.removeprefix("nlo_lab.") for s in SPINE)
    lines = ["```mermaid", "flowchart BT"]
    for s in stages:
        lines.append(f'    {s.replace(".", "_")}["{_label(s)}"]')
    for a, b in reduced:
        lines.append(f"    {a.replace('.', '_')} --> {b.replace('.', '_')}")
    lines.append("```")
    return (
        "\n".join(lines)
        + "\n\nAn arrow: the stage imports the one it points to (arrows implied by longer paths left out). "
        + f"Every stage uses the spine: {spine}. Generated by `tools/architecture.py` from the code."
    )


def figures(package: Path = PACKAGE) -> str:
    mods = modules(package)
    lines = {m: len(p.read_text(encoding="utf-8").splitlines()) for m, p in mods.items()}
    largest = max(lines, key=lines.get)
    return f"modules: {len(mods)}; largest: {largest} ({lines[largest]} lines); import circles: {len(cycles(package))}"


def current_picture(text: str) -> str:
    return text[text.index(BEGIN) + len(BEGIN): text.index(END)].strip()


def main(argv: list[str]) -> int:
    text = DOC.read_text(encoding="utf-8")
    picture = diagram()
    if "--print" in argv:
        print(picture)
        print(figures())
        return 0
    if "--check" in argv:
        if current_picture(text) != picture:
            print("docs/ARCHITECTURE.md: the picture is stale; run `python tools/architecture.py`")
            return 1
        return 0
    new = text[: text.index(BEGIN) + len(BEGIN)] + "\n" + picture + "\n" + text[text.index(END):]
    DOC.write_text(new, encoding="utf-8")
    print(f"wrote the picture into {DOC.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
