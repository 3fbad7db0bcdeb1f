"""Packaging: where bundled files are found, `nlo-lab lab`'s copy of the notebooks, a damaged install.

The wheel itself (built, installed in a clean venv, used from another folder)
is checked by ``make wheel-check`` (tools/wheel_check.py), which ``make test`` runs.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

import nlo_lab
import nlo_lab.paths as paths
from nlo_lab.cli import main
from nlo_lab.errors import CheckpointError, NloLabError, RobotDescriptionError

ROOT = Path(__file__).resolve().parents[2]


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


# ----------------------------------------------------------------------------- paths
def test_a_checkout_uses_the_top_level_folders():
    assert paths.ASSETS == ROOT / "assets" and paths.NOTEBOOKS_DIR == ROOT / "notebooks"
    assert paths.is_editable_checkout()
    assert (paths.ROBOTS_DIR / "yumi.urdf").is_file() and (paths.CHECKPOINTS_DIR / "yumi.pt").is_file()
    assert paths.is_bundled(paths.CHECKPOINTS_DIR / "nao.pt") and not paths.is_bundled(ROOT / "README.md")


def test_an_installed_package_uses_the_folders_inside_it(tmp_path, monkeypatch):
    (tmp_path / "nlo_lab" / "assets").mkdir(parents=True)
    (tmp_path / "assets").mkdir()  # a stray folder beside site-packages' package must not win
    monkeypatch.setattr(paths, "PACKAGE_DIR", tmp_path / "nlo_lab")
    assert paths._bundled_folder("assets") == tmp_path / "nlo_lab" / "assets"
    assert paths._bundled_folder("notebooks") == tmp_path / "notebooks"  # absent inside: the checkout layout


def test_the_version_has_one_source():
    tomllib = pytest.importorskip("tomllib")  # Python >= 3.11
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert "version" not in project["project"] and "version" in project["project"]["dynamic"]
    assert project["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "nlo_lab.__version__"}
    assert nlo_lab.__version__.count(".") == 2


def test_every_subpackage_goes_into_the_wheel():
    """pyproject.toml lists the packages by hand: a new folder of nlo_lab must be added there too."""
    tomllib = pytest.importorskip("tomllib")
    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    package = Path(nlo_lab.__file__).parent
    found = {".".join(p.parent.relative_to(package.parent).parts) for p in package.rglob("__init__.py")}
    assert found - listed == set(), "add these to [tool.setuptools] packages in pyproject.toml"


def test_pyproject_maps_the_top_level_folders_into_the_package():
    tomllib = pytest.importorskip("tomllib")
    setup = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert setup["package-dir"] == {"nlo_lab.assets": "assets", "nlo_lab.notebooks": "notebooks", "nlo_lab.docs": "docs"}
    data = setup["package-data"]
    for robot in paths.BUNDLED_ROBOTS:  # every bundled file matches a package-data pattern
        for f in (f"robots/{robot}.json", f"robots/{robot}.urdf", f"checkpoints/{robot}.pt"):
            assert any(Path(f).match(pattern) for pattern in data["nlo_lab.assets"]), f
    assert any(Path("01_x.ipynb").match(p) for p in data["nlo_lab.notebooks"])
    for doc in ("PAPER.md", "RESULTS.md", "figures/yumi_table3.png"):  # the paper's page and the results a notebook cites
        assert any(Path(doc).match(p) for p in data["nlo_lab.docs"]), doc
    assert (paths.DOCS_DIR / "PAPER.md").is_file() and (paths.DOCS_DIR / "RESULTS.md").is_file()


# ----------------------------------------------------------------------------- nlo-lab lab
def test_lab_copies_the_notebooks_and_keeps_the_learners_edits(tmp_path, capsys):
    from nlo_lab.lab import bundled_notebooks

    dest = tmp_path / "mine"
    assert main(["lab", "--copy-only", "--dir", str(dest)]) == 0
    assert capsys.readouterr().out.strip() == str(dest)
    shipped = bundled_notebooks()
    assert len(shipped) == len(list(paths.NOTEBOOKS_DIR.glob("[0-9][0-9]_*.ipynb"))) + 1
    for src in shipped:
        assert (dest / src.name).read_bytes() == src.read_bytes()
    edited = dest / shipped[0].name
    edited.write_text("my work")
    (dest / shipped[1].name).unlink()
    assert main(["lab", "--copy-only", "--dir", str(dest)]) == 0
    assert edited.read_text() == "my work"  # never overwritten
    assert (dest / shipped[1].name).read_bytes() == shipped[1].read_bytes()  # a deleted one comes back
    assert "copied 1 files" in capsys.readouterr().err


def test_lab_names_the_copies_of_another_version_and_never_edits_them(tmp_path, capsys):
    import json

    from nlo_lab.lab import bundled_notebooks, notebook_revision

    dest = tmp_path / "mine"
    assert main(["lab", "--copy-only", "--dir", str(dest)]) == 0
    capsys.readouterr()
    shipped = [p for p in bundled_notebooks() if p.suffix == ".ipynb"]
    assert len({notebook_revision(p) for p in shipped}) == len(shipped) and None not in {notebook_revision(p) for p in shipped}

    def rewrite(name, change):
        nb = json.loads((dest / name).read_text(encoding="utf-8"))
        change(nb)
        (dest / name).write_text(json.dumps(nb), encoding="utf-8")

    rewrite(shipped[0].name, lambda nb: nb["cells"][1].update(source="my work"))  # this version's, edited: not named
    rewrite(shipped[1].name, lambda nb: nb["metadata"].pop("nlo_lab"))  # copied before the stamps
    rewrite(shipped[2].name, lambda nb: nb["metadata"]["nlo_lab"].update(revision="0" * 16))  # another version's
    (dest / shipped[3].name).write_text("not a notebook")  # not ours to judge
    before = {p.name: p.read_bytes() for p in dest.iterdir()}
    assert main(["lab", "--copy-only", "--dir", str(dest)]) == 0
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 3, err  # what was copied, then the two lines
    assert "2 of your copies come from another version" in err[1], err
    assert shipped[1].name in err[1] and shipped[2].name in err[1], err
    assert shipped[0].name not in err[1] and shipped[3].name not in err[1], err
    assert "rename or move them and run `nlo-lab lab` again" in err[2]
    assert {p.name: p.read_bytes() for p in dest.iterdir()} == before  # told, never touched


def test_lab_default_folder_is_the_users(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("NLO_LAB_NOTEBOOKS", str(tmp_path / "nb"))
    assert main(["lab", "--copy-only"]) == 0
    assert capsys.readouterr().out.strip() == str(tmp_path / "nb")
    assert (tmp_path / "nb" / "01_robots_and_kinematics.ipynb").is_file()


def test_lab_into_a_file_is_one_line_exit_2(tmp_path, capsys):
    target = tmp_path / "file"
    target.write_text("x")
    assert main(["lab", "--copy-only", "--dir", str(target)]) == 2
    assert str(target) in one_error_line(capsys)


def test_lab_without_jupyterlab_says_which_extra(tmp_path, monkeypatch):
    import nlo_lab.lab.launch as lab

    monkeypatch.setattr(lab.importlib.util, "find_spec", lambda name: None)
    with pytest.raises(NloLabError, match=r"nlo_lab\[lab\]"):
        lab.lab_command(tmp_path, 8888)


def test_lab_command_binds_to_loopback(tmp_path):
    pytest.importorskip("jupyterlab")
    from nlo_lab.lab import lab_command

    cmd = lab_command(tmp_path, 9999)
    assert "--ip=127.0.0.1" in cmd and f"--notebook-dir={tmp_path}" in cmd


# ----------------------------------------------------------------------------- a damaged install
@pytest.fixture
def installed(monkeypatch):
    """Pretend to be a wheel install: the repair hint is pip's."""
    monkeypatch.setattr(paths, "is_editable_checkout", lambda: False)


@pytest.fixture
def bundled_checkpoints(tmp_path, monkeypatch):
    """An empty checkpoint folder that the package treats as its own assets (robot specs stay the real ones)."""
    import nlo_lab.model.checkpoint as checkpoint

    folder = tmp_path / "assets" / "checkpoints"
    folder.mkdir(parents=True)
    monkeypatch.setattr(checkpoint, "CHECKPOINTS_DIR", folder)
    real = paths.is_bundled
    monkeypatch.setattr(paths, "is_bundled", lambda p: real(p) or Path(p).resolve().is_relative_to(tmp_path.resolve()))
    monkeypatch.setattr(checkpoint, "is_bundled", paths.is_bundled)
    return folder


def test_a_missing_bundled_checkpoint_names_the_file_and_the_repair(bundled_checkpoints, installed, capsys):
    import nlo_lab.model.checkpoint as checkpoint

    tmp_path = bundled_checkpoints
    with pytest.raises(CheckpointError) as info:
        checkpoint.load_pretrained("nao")
    message = str(info.value)
    assert str(tmp_path / "nao.pt") in message and "pip install --force-reinstall --no-deps nlo_lab" in message
    assert main(["retarget", "demo:introduction_06", "--robot", "nao", "--iters", "1"]) == 2
    assert "pip install --force-reinstall" in one_error_line(capsys)


def test_a_corrupt_bundled_checkpoint_names_the_file_and_the_repair(bundled_checkpoints, installed):
    import nlo_lab.model.checkpoint as checkpoint

    (bundled_checkpoints / "nao.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(CheckpointError, match=r"cannot be read.*pip install --force-reinstall"):
        checkpoint.load_pretrained("nao")


def test_in_a_checkout_the_repair_is_git_checkout_or_retraining(tmp_path, monkeypatch):
    import nlo_lab.model.checkpoint as checkpoint

    assert "git checkout -- assets/checkpoints/nao.pt" in paths.repair_hint(paths.CHECKPOINTS_DIR / "nao.pt")
    moved = tmp_path / "nao.pt"
    shutil.copy(paths.CHECKPOINTS_DIR / "nao.pt", moved)
    monkeypatch.setattr(checkpoint, "checkpoint_path", lambda name: paths.CHECKPOINTS_DIR / f"{name}_gone.pt")
    with pytest.raises(CheckpointError, match=r"git checkout -- assets/checkpoints/nao_gone\.pt.*nlo-lab train --robot nao"):
        checkpoint.load_pretrained("nao")


def test_a_checkpoint_outside_the_package_gets_no_repair_hint(tmp_path, monkeypatch):
    import nlo_lab.model.checkpoint as checkpoint

    monkeypatch.setattr(checkpoint, "CHECKPOINTS_DIR", tmp_path)
    with pytest.raises(CheckpointError) as info:
        checkpoint.load_pretrained("nao")
    assert "nlo-lab train --robot nao" in str(info.value) and "git checkout" not in str(info.value)


@pytest.fixture
def bundled_copy(tmp_path, monkeypatch):
    """A copy of the bundled robots that the package treats as its own assets."""
    import nlo_lab.robot.spec as spec

    assets = tmp_path / "assets"
    shutil.copytree(paths.ROBOTS_DIR, assets / "robots")
    monkeypatch.setattr(paths, "ASSETS", assets)
    monkeypatch.setattr(spec, "ROBOTS_DIR", assets / "robots")
    return assets / "robots"


def test_a_missing_bundled_robot_is_a_damaged_install_not_an_unknown_name(bundled_copy, installed):
    from nlo_lab.robot import load_robot

    (bundled_copy / "yumi.json").unlink()
    with pytest.raises(RobotDescriptionError, match=r"yumi\.json.*pip install --force-reinstall"):
        load_robot("yumi")


def test_a_corrupt_bundled_urdf_names_the_file_and_the_repair(bundled_copy, installed):
    from nlo_lab.robot import load_robot

    (bundled_copy / "nao.urdf").write_text("<robot name='nao'><link name=")
    with pytest.raises(RobotDescriptionError, match=r"nao\.urdf.*pip install --force-reinstall"):
        load_robot("nao")
    (bundled_copy / "pepper.json").write_text("{")
    with pytest.raises(RobotDescriptionError, match=r"pepper\.json.*pip install --force-reinstall"):
        load_robot("pepper")


def test_a_users_own_robot_gets_no_repair_hint(tmp_path):
    from nlo_lab.robot import load_robot

    spec = tmp_path / "mine.json"
    spec.write_text('{"urdf": "mine.urdf", "base_link": "b", "actuated_joints": ["j"], "arms": {}}')
    with pytest.raises(RobotDescriptionError) as info:
        load_robot(spec)
    assert "reinstall" not in str(info.value) and "git checkout" not in str(info.value)


# ----------------------------------------------------------------------------- dependencies
def _imported_modules() -> dict[str, str]:
    """Top-level third-party modules the package imports -> one file that imports each."""
    import ast
    import sys

    found: dict[str, str] = {}
    for path in sorted((ROOT / "nlo_lab").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split(".")[0]
                if top not in sys.stdlib_module_names and top != "nlo_lab":
                    found.setdefault(top, str(path.relative_to(ROOT)))
    return found


def _canonical(name: str) -> str:
    import re

    return re.sub(r"[-_.]+", "-", name).lower()


def test_every_import_is_declared():
    tomllib = pytest.importorskip("tomllib")
    import importlib.metadata
    import re

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    requirements = project["dependencies"] + [r for extra in project["optional-dependencies"].values() for r in extra]
    declared = {_canonical(re.match(r"[A-Za-z0-9_.-]+", r).group(0)) for r in requirements}
    # where the import name is not the distribution's (and the distribution may not be installed here)
    known = {"cv2": "opencv-contrib-python", "PIL": "pillow", "zmq": "pyzmq", "umsgpack": "u-msgpack-python", "IPython": "ipython"}
    installed = importlib.metadata.packages_distributions()
    optional = {"pandas"}  # used when the user has it, never required (nlo_lab.batch's table as a DataFrame)
    missing = []
    for module, where in _imported_modules().items():
        if module in optional:
            continue
        candidates = [known[module]] if module in known else installed.get(module, [module])
        if not any(_canonical(c) in declared for c in candidates):
            missing.append(f"{module} (imported by {where})")
    assert not missing, f"imported but not declared in pyproject.toml: {missing}"


def test_no_declared_runtime_dependency_is_unused():
    tomllib = pytest.importorskip("tomllib")
    import re

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    runtime = {_canonical(re.match(r"[A-Za-z0-9_.-]+", r).group(0)) for r in project["dependencies"]}
    module_of = {"pytorch-kinematics": "pytorch_kinematics", "u-msgpack-python": "umsgpack", "pyzmq": "zmq",
                 "ipython": "IPython", "pillow": "PIL", "pose-format": "pose_format"}  # fmt: skip
    # Dependencies nlo_lab uses through another library's call, not by import: the call must be in the source.
    used_through = {"fast-simplification": "simplify_quadric_decimation"}  # trimesh's decimation needs it
    source = "\n".join(p.read_text(encoding="utf-8") for p in (ROOT / "nlo_lab").rglob("*.py"))
    for dependency, call in used_through.items():
        assert call in source, f"{dependency} is declared for {call}, which nlo_lab no longer calls"
    imported = set(_imported_modules())
    unused = sorted(d for d in runtime if d not in used_through and module_of.get(d, d.replace("-", "_")) not in imported)
    assert not unused, f"declared runtime dependencies that nlo_lab never imports: {unused}"
