"""The package's layout rules, read from the source with ast (nothing is imported).

- No module imports another module's private name (``from m import _x``, or
  ``m._x`` on an imported nlo_lab module): what a module keeps private, it may change.
- Every package re-exports its public names through ``__init__`` with ``__all__``,
  and every name in ``__all__`` is defined there.

How long a module may be is a review rule, not a number (CONTRIBUTING.md, "Modules"): one
concept per module, however long that concept is. ``PRIVATE_IMPORTS`` lists what is still
to make public; each entry must still be true (so an entry goes when it is fixed), and the
list only shrinks.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[2] / "nlo_lab"
# (importing module, imported module, name); to make public or move (issue 18, B and D)
PRIVATE_IMPORTS: set[tuple[str, str, str]] = set()


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


MODULES = _modules()


def _is_private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _resolve(module: str, path: Path, node: ast.ImportFrom) -> str:
    """The absolute module name of ``from <node.module> import ...`` inside ``module``."""
    if not node.level:
        return node.module or ""
    package = module.split(".") if path.name == "__init__.py" else module.split(".")[:-1]
    base = package[: len(package) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def private_imports(module: str, path: Path) -> set[tuple[str, str, str]]:
    """``(module, source, name)`` for every private name ``module`` takes from another nlo_lab module."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    found, aliases = set(), {}  # local name -> nlo_lab module it stands for
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            source = _resolve(module, path, node)
            if not source.startswith("nlo_lab"):
                continue
            for a in node.names:
                if f"{source}.{a.name}" in MODULES:  # a submodule: its attributes are checked below
                    aliases[a.asname or a.name] = f"{source}.{a.name}"
                elif _is_private(a.name) and source != module:
                    found.add((module, source, a.name))
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith("nlo_lab") and a.asname:
                    aliases[a.asname] = a.name
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and _is_private(node.attr):
            chain, value = [node.attr], node.value
            while isinstance(value, ast.Attribute):
                chain.append(value.attr)
                value = value.value
            if isinstance(value, ast.Name) and value.id in aliases:
                source = ".".join([aliases[value.id], *reversed(chain[1:])])
                if source in MODULES and source != module:
                    found.add((module, source, node.attr))
            elif isinstance(value, ast.Name) and value.id == "nlo_lab":  # import nlo_lab.x; nlo_lab.x._y
                source = ".".join(["nlo_lab", *reversed(chain[1:])])
                if source in MODULES and source != module:
                    found.add((module, source, node.attr))
    return found


def test_no_module_imports_another_modules_private_name():
    found = set().union(*(private_imports(m, p) for m, p in MODULES.items()))
    new = sorted(found - PRIVATE_IMPORTS)
    assert not new, "private names imported across modules (make them public or move them):\n" + "\n".join(map(str, new))
    fixed = sorted(PRIVATE_IMPORTS - found)
    assert not fixed, f"no longer imported, remove from PRIVATE_IMPORTS: {fixed}"


@pytest.mark.parametrize("package", sorted(m for m, p in MODULES.items() if p.name == "__init__.py" and m != "nlo_lab"))
def test_packages_export_their_public_names_with_all(package):
    tree = ast.parse(MODULES[package].read_text(encoding="utf-8"))
    defined, exported = set(), None
    for node in tree.body:
        if isinstance(node, ast.ImportFrom):
            defined |= {a.asname or a.name for a in node.names}
        elif isinstance(node, ast.FunctionDef) and node.name == "__getattr__":  # names imported on first use
            defined |= {c.value for c in ast.walk(node) if isinstance(c, ast.Constant) and isinstance(c.value, str)}
        elif isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            defined.add(node.name)
        elif isinstance(node, ast.Assign):
            for target in node.targets:
                if isinstance(target, ast.Name) and target.id == "__all__":
                    exported = ast.literal_eval(node.value)
                elif isinstance(target, ast.Name):
                    defined.add(target.id)
    assert exported, f"{package} has no __all__"
    assert len(set(exported)) == len(exported), f"{package}.__all__ repeats a name"
    missing = sorted(set(exported) - defined)
    assert not missing, f"{package}.__all__ names what it does not define or import: {missing}"


def test_the_checker_finds_what_it_looks_for(tmp_path):
    """The private-import check catches each form (so an empty result means something)."""
    src = tmp_path / "mod.py"
    src.write_text(
        "from nlo_lab.robot.collision import _DIFF\n"
        "from nlo_lab.robot import kinematics\n"
        "import nlo_lab.threads as be\n"
        "import nlo_lab.settings\n"
        "x = kinematics._x + be._current + nlo_lab.settings._number\n"
        "from nlo_lab.robot.collision import segment_distance, __all__\n",
        encoding="utf-8",
    )
    found = private_imports("nlo_lab.elsewhere", src)
    assert found == {
        ("nlo_lab.elsewhere", "nlo_lab.robot.collision", "_DIFF"),
        ("nlo_lab.elsewhere", "nlo_lab.robot.kinematics", "_x"),
        ("nlo_lab.elsewhere", "nlo_lab.threads", "_current"),
        ("nlo_lab.elsewhere", "nlo_lab.settings", "_number"),
    }
