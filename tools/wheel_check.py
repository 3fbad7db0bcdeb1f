"""Build the sdist and the wheel, install the wheel into a venv outside the repository, use it.

What a researcher does: ``pip install nlo_lab-*.whl`` into their own
environment and work from another folder. This script proves that works:

1. builds the sdist, then the wheel *from the sdist* (so both must carry the
   robots, checkpoints, recording and notebooks);
2. checks the wheel's file list (assets, notebooks, LICENSE);
3. installs the wheel into a venv in the user cache (not in the checkout). The
   venv is kept between runs so that torch and the other heavy dependencies are
   installed once per dependency set (venvs unused for three days are removed);
   nlo_lab itself is uninstalled and reinstalled from the new wheel every run,
   then ``pip check`` runs. A lock lets one check at a time use the cache, since
   several checkouts on one machine share it;
4. from an empty temporary folder, with the checkout out of reach: imports
   the package from site-packages, ``load_robot`` and ``load_pretrained`` for
   every robot, ``nlo-lab retarget demo:…``, ``nlo-lab demo``,
   ``nlo-lab lab --copy-only``, the console script at the declared entry point
   (``nlo_lab.__main__:main``) and ``python -m nlo_lab``, and a damaged install (a checkpoint moved
   away) giving one error line that names the file and the repair.

``--lowest`` does the same in a second cached venv where every runtime
dependency is the lowest release ``pyproject.toml`` allows (``name>=X`` becomes
``name==X``; torch stays the machine's CPU build, the only one reachable here):
the lower bounds are tested, not guessed.

Run: ``make wheel-check`` (``make test`` runs it with and without ``--lowest``).
Exit status 1 on the first failure, with what failed.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TORCH = "torch==2.13.0"  # the Makefile's CPU build: a bare `torch` may pull a multi-GB GPU build
ROBOTS = ("nao", "pepper", "yumi")


def fail(message: str) -> None:
    print(f"wheel-check: FAILED: {message}", file=sys.stderr)
    sys.exit(1)


def outside_env() -> dict:
    """The environment without Python's and nlo_lab's variables: a PYTHONPATH to a checkout (its ``nlo_lab.egg-info``)
    would make pip see nlo_lab installed there, and skip the wheel."""
    return {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "VIRTUAL_ENV", "NLO_LAB"))}


def run(cmd: list[str], cwd: Path | None = None, env: dict | None = None, expect: int = 0) -> subprocess.CompletedProcess:
    proc = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True)
    if proc.returncode != expect:
        fail(f"`{' '.join(map(str, cmd))}` exited {proc.returncode} (expected {expect})\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    return proc


def cache_root() -> Path:
    base = os.environ.get("NLO_LAB_WHEEL_CHECK_CACHE") or Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "nlo_lab"
    return Path(base) / "wheel-check"


def runtime_requirements() -> list[str]:
    """The ``dependencies`` of pyproject.toml, as written."""
    import tomllib

    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]


def lowest_constraints() -> list[str]:
    """``name==X`` for every runtime requirement with a lower bound ``>=X`` (torch excepted)."""
    out = []
    for req in runtime_requirements():
        m = re.match(r"\s*([A-Za-z0-9_.-]+)\s*(?:\[.*?\])?\s*(.*)", req)
        name, spec = m.group(1), m.group(2)
        low = re.search(r">=\s*([0-9][^,;\s]*)", spec)
        if low and name.lower() != "torch":
            out.append(f"{name}=={low.group(1)}")
    return out


def dependency_key(lowest: bool) -> str:
    """Changes when the declared dependencies or the Python version change (then the venv is rebuilt)."""
    payload = f"{sys.version_info[:2]} {TORCH} {runtime_requirements()} {lowest}"
    return hashlib.sha256(payload.encode()).hexdigest()[:12]


def build(out: Path) -> Path:
    """The sdist, then the wheel built from it; returns the wheel."""
    t0 = time.perf_counter()
    # The dev venv's setuptools (>= 77, as pyproject asks), without build isolation: no download.
    build_sdist = f"from setuptools import build_meta; print(build_meta.build_sdist({str(out)!r}))"
    sdist = out / run([sys.executable, "-c", build_sdist], cwd=ROOT).stdout.strip().splitlines()[-1]
    names = tarfile_names(sdist)
    for needed in ("assets/checkpoints/yumi.pt", "assets/robots/yumi.urdf", "notebooks/01_robots_and_kinematics.ipynb", "LICENSE"):
        if not any(n.endswith(needed) for n in names):
            fail(f"the sdist {sdist.name} lacks {needed}")
    run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--no-build-isolation", "-w", out, sdist])
    wheels = sorted(out.glob("nlo_lab-*.whl"))
    if len(wheels) != 1:
        fail(f"expected one wheel in {out}, found {[w.name for w in wheels]}")
    print(f"wheel-check: built {sdist.name} ({sdist.stat().st_size / 1e6:.1f} MB) and {wheels[0].name} "
          f"({wheels[0].stat().st_size / 1e6:.1f} MB) in {time.perf_counter() - t0:.0f} s")  # fmt: skip
    return wheels[0]


def tarfile_names(path: Path) -> list[str]:
    import tarfile

    with tarfile.open(path) as tar:
        return tar.getnames()


def check_wheel_contents(wheel: Path) -> None:
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
    needed = [f"nlo_lab/assets/robots/{r}.{ext}" for r in ROBOTS for ext in ("json", "urdf")]
    needed += [f"nlo_lab/assets/checkpoints/{r}.pt" for r in ROBOTS]
    needed += ["nlo_lab/assets/recordings/holistic_both_hands_47f.pose", "nlo_lab/notebooks/README.md"]
    needed += ["nlo_lab/docs/PAPER.md", "nlo_lab/docs/RESULTS.md", "nlo_lab/human/readers/h5_extract.py"]
    needed += [f"nlo_lab/docs/figures/{p.name}" for p in sorted((ROOT / "docs" / "figures").glob("*.png"))]
    needed += [f"nlo_lab/notebooks/{p.name}" for p in sorted((ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))]
    missing = [n for n in needed if n not in names]
    if missing:
        fail(f"the wheel lacks {missing}")
    if not any(n.endswith(".dist-info/licenses/LICENSE") for n in names):
        fail("the wheel lacks LICENSE in its .dist-info/licenses")
    stray = sorted(n for n in names if n.startswith("nlo_lab/assets/") and n.endswith(".py"))
    if stray:
        fail(f"the wheel carries the asset generator scripts {stray}")


def venv_with_deps(wheel: Path, lowest: bool, outside: Path) -> Path:
    """The cached venv, with the new wheel installed in place of the last one; returns its python.

    pip runs in ``outside`` (a folder of its own) with :func:`outside_env`: from the checkout (``python -m`` puts
    the current folder first on sys.path) pip found the checkout's ``nlo_lab.egg-info``, "uninstalled" nothing
    (outside the environment) and took the wheel as already installed: the venv kept an old nlo_lab."""
    kind = "lowest" if lowest else "latest"
    root = cache_root()
    venv = root / f"{kind}-{dependency_key(lowest)}"
    py = venv / "bin" / "python"
    constraints = root / f"{venv.name}.constraints.txt"
    pins = ["-c", constraints] if lowest else []
    root.mkdir(parents=True, exist_ok=True)
    constraints.write_text("\n".join(lowest_constraints()) + "\n")
    if not (venv / ".ready").exists():
        shutil.rmtree(venv, ignore_errors=True)  # a half-made venv from an interrupted run
        t0 = time.perf_counter()
        run([sys.executable, "-m", "venv", "--clear", venv])
        run([py, "-m", "pip", "install", "--quiet", TORCH], cwd=outside, env=outside_env())
        run([py, "-m", "pip", "install", "--quiet", *pins, wheel], cwd=outside, env=outside_env())
        (venv / ".ready").touch()
        print(f"wheel-check: created {venv} with the dependencies in {time.perf_counter() - t0:.0f} s (cached for later runs)")
    (venv / ".ready").touch()  # its time says when it was last used (see prune)
    run([py, "-m", "pip", "uninstall", "--quiet", "--yes", "nlo_lab"], cwd=outside, env=outside_env())
    run([py, "-m", "pip", "install", "--quiet", *pins, wheel], cwd=outside, env=outside_env())  # new dependencies, if any, come in here
    run([py, "-m", "pip", "check"], cwd=outside, env=outside_env())
    site = Path(run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"], cwd=outside,
                    env=outside_env()).stdout.strip())
    with zipfile.ZipFile(wheel) as zf:
        packed = sorted(n for n in zf.namelist() if n.startswith("nlo_lab/") and n.endswith(".py"))
    installed = sorted(p.relative_to(site).as_posix() for p in (site / "nlo_lab").rglob("*.py"))
    if installed != packed:
        fail(f"the venv's nlo_lab is not the wheel's: {sorted(set(packed) ^ set(installed))[:10]}")
    if lowest:  # pip installed exactly these (constraints are binding) or failed above
        print(f"wheel-check: lowest versions: {', '.join(lowest_constraints())} (torch: {TORCH})")
    return py


SMOKE = r"""
import json, sys
import nlo_lab, nlo_lab.paths as paths
from nlo_lab.robot import load_robot, known_robots
from nlo_lab.model import load_pretrained
assert "site-packages" in nlo_lab.__file__, nlo_lab.__file__
assert paths.ASSETS.parent == paths.PACKAGE_DIR, paths.ASSETS
assert paths.DOCS_DIR.parent == paths.PACKAGE_DIR and (paths.DOCS_DIR / "PAPER.md").is_file(), paths.DOCS_DIR  # docs a notebook cites
out = {"version": nlo_lab.__version__, "robots": known_robots(), "assets": str(paths.ASSETS)}
for name in known_robots():
    robot = load_robot(name)
    model = load_pretrained(robot)
    out[name] = [robot.n_joints, sum(p.numel() for p in model.parameters())]
# what the lowest versions must also do: the reference FK, a .pose file, a plot, the widgets
import matplotlib
matplotlib.use("Agg")
from nlo_lab.robot.pk_chain import PKChain
from nlo_lab.human import load_demonstration
from nlo_lab.viz import plot_convergence
import nlo_lab.lab
robot = load_robot("yumi")
q = robot.neutral_q[None]
ours, ref = robot.forward_kinematics(q), PKChain(robot).forward_kinematics(q)
out["pk_max_diff"] = max(float((ours[k] - ref[k]).abs().max()) for k in ref)
assert out["pk_max_diff"] < 1e-4, out["pk_max_diff"]
out["pose_frames"] = len(load_demonstration(paths.RECORDINGS_DIR / "holistic_both_hands_47f.pose"))
# an .h5 in the authors' layout: read by the installed reader's own HDF5 process (h5_extract.py, python -I)
import h5py, numpy as np
with h5py.File("arms.h5", "w") as f:
    g = f.create_group("word")
    for s, y in (("l", 0.17), ("r", -0.17)):
        t = np.zeros((9, 1))
        g[f"{s}_up_pos"], g[f"{s}_fr_pos"], g[f"{s}_hd_pos"] = t + [0, y, 1.4], t + [0.05, y, 1.15], t + [0.3, y, 1.2]
out["h5_frames"] = len(load_demonstration("arms.h5"))
plot_convergence([3.0, 2.0, 1.0])
print(json.dumps(out))
"""


def smoke(py: Path, work: Path) -> None:
    env = outside_env()
    env["PATH"] = f"{py.parent}{os.pathsep}{env.get('PATH', '')}"
    env["HOME"] = str(work / "home")  # `nlo-lab lab`'s default folder lands here, not in the real home
    cli = py.parent / "nlo-lab"
    t0 = time.perf_counter()
    info = json.loads(run([py, "-c", SMOKE], cwd=work, env=env).stdout.strip().splitlines()[-1])
    if info["robots"] != list(ROBOTS):
        fail(f"known_robots() in the installed package is {info['robots']}")
    summary = json.loads(run([cli, "retarget", "demo:introduction_06", "--robot", "nao", "--iters", "5", "--json", "--out", "nao_out"],
                             cwd=work, env=env).stdout.strip().splitlines()[-1])  # fmt: skip
    for name in ("trajectory.npz", "trajectory.csv", "viewer.html"):
        if not (work / "nao_out" / name).is_file():
            fail(f"nlo-lab retarget --out nao_out wrote no {name}")
    demo = run([cli, "demo"], cwd=work, env=env).stdout
    if "retargeted" not in demo or not (work / "out" / "demo" / "trajectory.csv").is_file():
        fail(f"nlo-lab demo did not retarget:\n{demo[-2000:]}")
    folder = run([cli, "lab", "--copy-only"], cwd=work, env=env).stdout.strip().splitlines()[-1]
    copied = sorted(p.name for p in Path(folder).glob("*.ipynb"))
    if len(copied) != len(list((ROOT / "notebooks").glob("[0-9][0-9]_*.ipynb"))) or not Path(folder).is_relative_to(work / "home"):
        fail(f"nlo-lab lab --copy-only copied {copied} to {folder}")
    # The program's first lines take the signals (nlo_lab/__main__.py): the console script and `python -m nlo_lab` start there.
    module, func = re.search(r'^nlo-lab = "(\S+):(\S+)"$', (ROOT / "pyproject.toml").read_text(), re.M).groups()
    if f"from {module} import {func}" not in cli.read_text():
        fail(f"the installed nlo-lab script does not start at the declared entry point {module}:{func}:\n{cli.read_text()}")
    if "usage: nlo-lab" not in run([py, "-m", "nlo_lab", "--help"], cwd=work, env=env).stdout:
        fail("python -m nlo_lab --help printed no usage")
    # `nlo-lab batch` without its extra (dask is not a core dependency): one line naming the extra, exit 2.
    sample = Path(info["assets"]) / "recordings" / "holistic_both_hands_47f.pose"
    err = run([cli, "batch", sample, "--robot", "nao", "--out", "batch_out", "--iters", "1"], cwd=work, env=env, expect=2).stderr
    if len(err.strip().splitlines()) != 1 or 'pip install "nlo_lab[batch]"' not in err:
        fail(f"nlo-lab batch without the batch extra gave:\n{err}")
    # A damaged install: one line naming the file and the repair, exit 2.
    ckpt = Path(info["assets"]) / "checkpoints" / "yumi.pt"
    moved = ckpt.with_suffix(".moved")
    ckpt.rename(moved)
    try:
        err = run([cli, "retarget", "demo:introduction_06", "--robot", "yumi", "--iters", "1"], cwd=work, env=env, expect=2).stderr
    finally:
        moved.rename(ckpt)
    lines = err.strip().splitlines()
    if len(lines) != 1 or str(ckpt) not in lines[0] or "pip install --force-reinstall" not in lines[0]:
        fail(f"a missing bundled checkpoint gave:\n{err}")
    print(f"wheel-check: from {work}: nlo_lab {info['version']} imported from site-packages; load_robot + load_pretrained "
          f"{', '.join(ROBOTS)}; PKChain; the .pose sample ({info['pose_frames']} frames); an .h5 ({info['h5_frames']} frames); a plot; retarget (frechet {summary['frechet_m']:.3f} m); demo; lab --copy-only ({len(copied)} notebooks); the script at {module}:{func}, python -m nlo_lab; "
          f"batch without its extra -> exit 2; damaged install -> exit 2 naming {ckpt.name} ({time.perf_counter() - t0:.0f} s)")  # fmt: skip


def prune(root: Path, days: float = 3.0) -> None:
    """Remove cached venvs not used for ``days`` (other checkouts may still use other dependency sets)."""
    for ready in root.glob("*/.ready"):
        if time.time() - ready.stat().st_mtime > days * 86400:
            shutil.rmtree(ready.parent, ignore_errors=True)


@contextlib.contextmanager
def cache_lock():
    """One wheel check at a time per cache: checkouts on one machine share it."""
    import fcntl

    root = cache_root()
    root.mkdir(parents=True, exist_ok=True)
    with open(root / ".lock", "w") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)  # waits for another checkout's run to finish
        try:
            yield root
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def main() -> int:
    lowest = "--lowest" in sys.argv[1:]
    with cache_lock() as root, tempfile.TemporaryDirectory(prefix="nlo_lab-wheel-check-") as tmp:
        prune(root)
        tmp = Path(tmp)
        (tmp / "dist").mkdir()
        (tmp / "work" / "home").mkdir(parents=True)
        wheel = build(tmp / "dist")
        check_wheel_contents(wheel)
        py = venv_with_deps(wheel, lowest, tmp / "work")
        smoke(py, tmp / "work")
    print(f"wheel-check{' --lowest' if lowest else ''}: OK")
    return 0


if __name__ == "__main__":
    sys.exit(main())
