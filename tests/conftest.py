"""Fixtures and builders shared by the test folders (CONTRIBUTING.md, "Tests").

No test module imports another: what several need lives here, as a fixture. A builder is a
session fixture that returns a function or a class, so a test asks for it by name and calls it
(``def test_x(make_demo): demo = make_demo(T=5)``).

- ``shared_file`` / ``shared_pose``: files of ``../shared`` beside the checkout (the real
  recordings and the founding reference). A user's clone does not have that folder: a test
  that needs it is skipped with the path it looked for.
- ``robot64``: a robot loaded once per session in float64 (for gradient and agreement checks);
  ``each_robot64``: each shipped robot in float64 in turn (a module's tests run once per robot);
  ``random_angles``: random angles inside a robot's limits.
- ``nao``, ``robots``: robots as the package loads them (float32), once per module.
- ``robot_data``: the robots of the example-robot-data wheel (real URDFs we did not write).
- ``make_demo``: a synthetic two-arm demonstration with known segment lengths.
- ``random_feasible_pose`` / ``demonstration_from_robot``: poses a robot can take, and the human
  targets it meets exactly there (round trips).
- ``write_authors_h5``: a file in the authors' HDF5 layout; ``pose_files``: Holistic-like ``.pose`` files.
- ``assert_one_line_error``: what a command-line fault must look like; ``work``: a fresh current
  folder; ``demo_npz``: a small demonstration archive in it; ``others_folder``: a folder of
  another user; ``nan_loss``: the pipeline's optimisation made to end in a NaN loss.
- ``checkout_script``: a script of ``tools/`` or ``benchmarks/`` imported by its path.
- ``lab_browser``: JupyterLab driven in Debian's Chromium (``tools/lab_browser.py``, shared with
  ``benchmarks/viewer.py``). A test marked ``browser`` is skipped, with the reason, where that
  browser or playwright is missing.
- ``tests/fuzz`` is importable (``import targets``, ``import make_corpus``): the fuzz corpus's
  builders, its special files (FIFO, /dev/zero, ...) and the memory budget, for any test.

Markers (pyproject.toml, ``--strict-markers``): ``browser`` drives Chromium, ``slow`` is one of the
long tests; ``make test-fast`` runs neither. A test module may still define a fixture of the same
name as one here; pytest then uses the module's.
"""

from __future__ import annotations

import functools
import importlib.util
import os
import sys
from collections.abc import Callable
from pathlib import Path
from types import ModuleType

# matplotlib's font cache in the checkout, not the account's: a cache another install rewrote (seen once: only the
# system's fonts, none of matplotlib's own) made a notebook print "findfont" warnings a browser test reads as a fault.
# Set before anything imports matplotlib; the notebooks' kernels and JupyterLab inherit it.
os.environ.setdefault("MPLCONFIGDIR", str(Path(__file__).resolve().parents[1] / "build" / "matplotlib"))

import h5py
import numpy as np
import pytest
import torch

from nlo_lab.human.demonstration import FINGERS, SIDES, Demonstration
from nlo_lab.human.transforms import quat_to_matrix
from nlo_lab.objective import robot_points
from nlo_lab.robot import Robot, load_robot


def pytest_sessionstart(session) -> None:
    """Build that font cache here, once, not in the first notebook a test runs (where a slow build logs a warning)."""
    import matplotlib.font_manager  # noqa: F401  (importing it builds the cache where there is none)


ROOT = Path(__file__).resolve().parents[1]  # the checkout
SHARED = ROOT.parent / "shared"  # beside the checkout (and in CI), never in a user's clone
sys.path.insert(0, str(ROOT / "tests" / "fuzz"))  # test modules are imported by path: name the helpers' folder
SHARED_POSE = SHARED / "data" / "pose"  # the real MediaPipe recordings


def _shared(path: Path) -> Path:
    if not path.exists():
        pytest.skip(f"shared file not available at {path}")
    return path


@pytest.fixture(scope="session")
def shared_file() -> Callable[..., Path]:
    """``shared_file("reference", "ROBOT_FACTS.md")`` -> the path under ``../shared``, or skip."""
    return lambda *parts: _shared(SHARED.joinpath(*parts))


@pytest.fixture(scope="session")
def shared_pose() -> Callable[[str], Path]:
    """``shared_pose("holistic_world_97f.pose")`` -> a shared real recording, or skip."""
    return lambda name: _shared(SHARED_POSE / name)


@functools.cache
def _robot64(name: str) -> Robot:
    return load_robot(name).to(dtype=torch.float64)


@pytest.fixture(scope="session")
def robot64() -> Callable[[str], Robot]:
    """``robot64("yumi")`` -> the robot in float64, loaded once per session (tests must not change it)."""
    return _robot64


@pytest.fixture(scope="module", params=("yumi", "nao", "pepper"))
def each_robot64(request) -> Robot:
    """Each shipped robot in float64, one after the other."""
    return _robot64(request.param)


@pytest.fixture(scope="session")
def random_angles() -> Callable[[Robot, int, int], torch.Tensor]:
    """``random_angles(robot, batch, seed)`` -> ``(batch, n)`` angles drawn uniformly inside the limits."""

    def draw(robot: Robot, batch: int, seed: int) -> torch.Tensor:
        u = torch.rand(batch, robot.n_joints, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)
        return robot.lower_limits + u.to(robot.lower_limits.dtype) * (robot.upper_limits - robot.lower_limits)

    return draw


@pytest.fixture(scope="module")
def nao() -> Robot:
    return load_robot("nao")


@pytest.fixture(scope="module")
def robots() -> dict[str, Robot]:
    """The three shipped robots by name."""
    return {name: load_robot(name) for name in ("yumi", "nao", "pepper")}


@pytest.fixture(scope="module")
def one_torch_thread():
    """One torch thread for a module (``pytestmark = pytest.mark.usefixtures("one_torch_thread")``), as the command
    line trains and retargets: two threads spin against each other on a busy 2-core machine (nlo_lab.threads)."""
    from nlo_lab.threads import single_thread

    with single_thread(1):
        yield


def _example_robot_data() -> Path | None:
    """The robots folder of the example-robot-data wheel (the test extra), or None."""
    from importlib import metadata

    try:
        folder = Path(metadata.distribution("example-robot-data").locate_file("cmeel.prefix/share/example-robot-data/robots"))
    except metadata.PackageNotFoundError:
        return None
    return folder if folder.is_dir() else None


@pytest.fixture(scope="session")
def robot_data() -> Path:
    """``robots/`` of the example-robot-data wheel: real URDFs we did not write (skip without it)."""
    folder = _example_robot_data()
    if folder is None:
        pytest.skip("example-robot-data is not installed (pip install 'nlo_lab[test]')")
    return folder


# ----------------------------------------------------------------------------- the checkout's scripts
@functools.cache
def _checkout_script(relative: str) -> ModuleType:
    path = ROOT / relative
    spec = importlib.util.spec_from_file_location("nlo_lab_" + "_".join(path.with_suffix("").parts[-2:]), path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _capsule_ends_as_written(fitted: dict, written: dict) -> dict:
    """``fitted`` (a spec's collision fields from ``assets/robots/fit_capsules.py``) with each capsule's two ends in the
    order ``written`` gives that capsule's: a capsule is the same whichever end comes first, and the fit's principal
    axes come from an SVD whose sign OpenBLAS's kernels choose per CPU (one machine gave YuMi's left hand base from its
    top end, 2026-11-27). Nothing else is changed: the names, the ends themselves, the radii and the pairs compare as
    they are."""
    ends = {c["name"]: (c["p0"], c["p1"]) for c in written.get("capsules", [])}
    out = dict(fitted)
    out["capsules"] = [{**c, "p0": c["p1"], "p1": c["p0"]} if ends.get(c["name"]) == (c["p1"], c["p0"]) else c
                       for c in fitted.get("capsules", [])]
    return out


@pytest.fixture(scope="session")
def capsule_ends_as_written() -> Callable[[dict, dict], dict]:
    """``capsule_ends_as_written(fitted, written)``: see :func:`_capsule_ends_as_written`."""
    return _capsule_ends_as_written


@pytest.fixture(scope="session")
def checkout_script() -> Callable[[str], ModuleType]:
    """``checkout_script("tools/architecture.py")``: a script of the checkout (``tools/``, ``benchmarks/``) imported
    by its path, once a session."""
    return _checkout_script


# ----------------------------------------------------------------------------- the real browser
@pytest.fixture(scope="session")
def lab_browser() -> ModuleType:
    """``tools/lab_browser.py``: ``Lab``, ``LabPage``, ``CHROMIUM``, ``CHROMIUM_ARGS``, ``hue_mask``, ``browser_missing``."""
    return _checkout_script("tools/lab_browser.py")


def pytest_runtest_setup(item: pytest.Item) -> None:
    if item.get_closest_marker("browser") is not None:
        missing = _checkout_script("tools/lab_browser.py").browser_missing()
        if missing:
            pytest.skip(missing)


# ----------------------------------------------------------------------------- demonstrations
def _random_rotations(rng, n):
    q = rng.normal(size=(n, 4))
    return quat_to_matrix(q)


def _make_demo(T=20, fps=10.0, seed=0, upper=(0.3, 0.25), fore=(0.28, 0.22)) -> Demonstration:
    """Two arms with known segment lengths moving smoothly; hands with fingers; random wrist rotations."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) / fps
    arms = np.zeros((T, 2, 3, 3))
    fingers = np.zeros((T, 2, 5, 2, 3))
    for s, sign in enumerate((1.0, -1.0)):
        arms[:, s, 0] = [0.0, 0.18 * sign, 0.0]
        d1 = np.stack([np.sin(t), 0.2 * sign * np.ones(T), -np.cos(t)], -1)
        d1 /= np.linalg.norm(d1, axis=-1, keepdims=True)
        d2 = np.stack([np.cos(0.5 * t), sign * 0.3 * np.sin(t), -0.5 * np.ones(T)], -1)
        d2 /= np.linalg.norm(d2, axis=-1, keepdims=True)
        arms[:, s, 1] = arms[:, s, 0] + upper[s] * d1
        arms[:, s, 2] = arms[:, s, 1] + fore[s] * d2
        fingers[:, s] = arms[:, s, 2][:, None, None] + rng.normal(scale=0.05, size=(5, 2, 3))
    R = _random_rotations(rng, T * 2).reshape(T, 2, 3, 3)
    return Demonstration(fps, arms, np.ones((T, 2, 3), bool), R, np.ones((T, 2), bool), fingers, np.ones((T, 2, 5), bool),
                         name="synthetic", meta={"k": 1})



@pytest.fixture(scope="session")
def make_demo() -> Callable[..., Demonstration]:
    """``make_demo(T=20, fps=10.0, seed=0, upper=(0.3, 0.25), fore=(0.28, 0.22))``: two arms with known segment lengths."""
    return _make_demo


def _rotz(a):
    return quat_to_matrix(np.array([0, 0, np.sin(a / 2), np.cos(a / 2)]))


def _glove_points(T, rng):
    """(T, 16, 3) in a hand frame: wrist at 0, fingers along +x, thumb..pinky from +y to -y (a right hand)."""
    pts = np.zeros((T, 16, 3))
    for f, y in enumerate((0.04, 0.025, 0.0, -0.02, -0.035)):
        base = np.array([0.09 if f else 0.04, y, 0.0])
        pts[:, 1 + 3 * f] = base
        pts[:, 2 + 3 * f] = base + [0.03, 0, -0.01]
        pts[:, 3 + 3 * f] = base + [0.06, 0, -0.02]
    return pts + rng.normal(scale=1e-3, size=pts.shape)


def _write_authors_h5(path, groups=("word_b", "word_a", "sentence_1"), T=12, yaw=0.3, offset=(1.0, 2.0, 0.9),
                     glove=True, fps=None):
    """Write a file in the authors' layout. The capture frame = our body frame turned by ``yaw`` about Z and shifted."""
    rng = np.random.default_rng(3)
    R = _rotz(yaw)  # R_capture_body
    truth = {}
    with h5py.File(path, "w") as f:
        if fps is not None:
            f.attrs["fps"] = fps
        for g, name in enumerate(groups):
            grp = f.create_group(name)
            body = {}
            for s, sign in (("l", 1.0), ("r", -1.0)):
                t = np.arange(T)[:, None]
                sh = np.array([0.0, 0.17 * sign, 0.0]) + np.zeros((T, 3))
                el = sh + np.concatenate([0.05 * np.sin(t / 3), 0.05 * sign + 0 * t, -0.19 + 0 * t], 1)
                wr = el + np.concatenate([0.2 + 0 * t, 0.02 * np.cos(t / 2), 0.1 + 0 * t], 1)
                body[s] = (sh, el, wr)
                for part, p in zip(("up", "fr", "hd"), (sh, el, wr), strict=True):
                    grp[f"{s}_{part}_pos"] = p @ R.T + np.array(offset)
                    grp[f"{s}_{part}_quat"] = np.tile([0, 0, np.sin(0.1 * g), np.cos(0.1 * g)], (T, 1))
                grp[f"{s}_glove_angle"] = rng.uniform(0, 90, size=(T, 14))
                if glove:
                    hand = _glove_points(T, rng)  # hand frame = body frame turned by 0.2 rad about Y
                    Ry = quat_to_matrix(np.array([0, np.sin(0.1), 0, np.cos(0.1)]))
                    grp[f"{s}_glove_pos"] = (hand @ Ry.T) @ R.T + 5.0  # any offset: pinned to hd_pos
                    body[s + "_glove"] = (hand @ Ry.T, Ry)
            truth[name] = body
    return truth


@pytest.fixture(scope="session")
def write_authors_h5() -> Callable[..., dict]:
    """``write_authors_h5(path, groups=..., T=12, yaw=0.3, ...)`` -> the truth written (see the function)."""
    return _write_authors_h5


class PoseFiles:
    """Holistic-like ``.pose`` files written with pose-format's own writer, and the truth they hold.

    The body moves in our body frame (X forward, Y left, Z up); the file stores it the way MediaPipe
    does: the image landmarks in pixels, the world landmarks in metres about the hip centre.
    """

    BODY8 = ["LEFT_SHOULDER", "RIGHT_SHOULDER", "LEFT_ELBOW", "RIGHT_ELBOW", "LEFT_WRIST", "RIGHT_WRIST", "LEFT_HIP", "RIGHT_HIP"]
    HAND21 = ["WRIST"] + [f"{f}_{p}" for f in ("THUMB",) for p in ("CMC", "MCP", "IP", "TIP")] + [
        f"{f}_FINGER_{p}" if f != "PINKY" else f"PINKY_{p}" for f in ("INDEX", "MIDDLE", "RING", "PINKY") for p in ("MCP", "PIP", "DIP", "TIP")
    ]
    W, H, PX_PER_M, FPS = 640, 480, 800.0, 25

    @staticmethod
    def body_truth(T: int) -> dict[str, np.ndarray]:
        """Known body-frame points [m] (X forward, Y left, Z up): name -> (T, 3)."""
        t = np.arange(T)[:, None] / PoseFiles.FPS
        pts = {}
        for side, sign in (("LEFT", 1.0), ("RIGHT", -1.0)):
            sh = np.array([0.0, 0.18 * sign, 0.0]) + 0 * t
            el = sh + np.concatenate([0.05 + 0.05 * np.sin(3 * t), 0.06 * sign + 0 * t, -0.18 + 0 * t], 1)
            wr = el + np.concatenate([0.2 + 0 * t, -0.04 * sign + 0.05 * np.cos(2 * t), 0.12 + 0 * t], 1)
            pts[f"{side}_SHOULDER"], pts[f"{side}_ELBOW"], pts[f"{side}_WRIST"] = sh, el, wr
            pts[f"{side}_HIP"] = np.array([0.0, 0.12 * sign, -0.5]) + 0 * t
        return pts

    @staticmethod
    def hand_truth(T: int, sign: float) -> np.ndarray:
        """(T, 21, 3) hand points relative to the wrist [m], body frame: fingers forward (+X), palm down."""
        pts = np.zeros((21, 3))
        for f, y in enumerate((0.035, 0.022, 0.0, -0.02, -0.035)):  # thumb..pinky from the left for the right hand
            start = 1 + 4 * f
            base = np.array([0.03 if f == 0 else 0.09, -sign * y, 0.0])
            for k in range(4):
                pts[start + k] = base + (k - (1 if f == 0 else 0)) * np.array([0.025, 0.0, -0.005])
        return np.broadcast_to(pts, (T, 21, 3)).copy()

    @staticmethod
    def to_camera(p: np.ndarray) -> np.ndarray:
        """Body frame (X fwd, Y left, Z up) -> camera-aligned axes (x right, y down, z away) for a person facing the camera."""
        return np.stack([p[..., 1], -p[..., 2], -p[..., 0]], -1)

    def write(self, path, T=40, world=True, hand_missing=(), left_hand=True, conf_overrides=None, data_overrides=None,
              fps=None, people=1):
        """Write a Holistic-like .pose with pose-format's writer; returns the body and hand truth."""
        from pose_format import Pose
        from pose_format.numpy import NumPyPoseBody
        from pose_format.pose_header import PoseHeader, PoseHeaderComponent, PoseHeaderDimensions

        W, H, PX_PER_M, BODY8, HAND21 = self.W, self.H, self.PX_PER_M, self.BODY8, self.HAND21
        fps = self.FPS if fps is None else fps
        body = self.body_truth(T)
        comps = [("POSE_LANDMARKS", BODY8), ("LEFT_HAND_LANDMARKS", HAND21), ("RIGHT_HAND_LANDMARKS", HAND21)]
        if world:
            comps.append(("POSE_WORLD_LANDMARKS", BODY8))
        header = PoseHeader(0.2, PoseHeaderDimensions(W, H, 0),
                            [PoseHeaderComponent(n, pts, [], [], "XYZC") for n, pts in comps])
        cols = []
        confs = []
        centre = np.array([W / 2, H / 2])
        hip_c = (body["LEFT_HIP"] + body["RIGHT_HIP"]) / 2
        # POSE_LANDMARKS: orthographic image, z on MediaPipe's normalised scale (the reader ignores it)
        img = np.stack([self.to_camera(body[n]) for n in BODY8], 1)
        cols.append(np.concatenate([img[..., :2] * PX_PER_M + centre, img[..., 2:] * PX_PER_M / W], -1))
        confs.append(np.full((T, 8), 0.9))
        hands = {}
        for side, sign in (("LEFT", 1.0), ("RIGHT", -1.0)):
            rel = self.hand_truth(T, sign)
            hands[side] = rel
            cam = self.to_camera(rel)
            wrist_px = self.to_camera(body[f"{side}_WRIST"])[:, :2] * PX_PER_M + centre + 7.0  # hand model's wrist a bit off
            h = np.concatenate([cam[..., :2] * PX_PER_M + wrist_px[:, None], cam[..., 2:] * PX_PER_M / W], -1)
            c = np.ones((T, 21))
            missing = list(hand_missing) if side == "RIGHT" else ([] if left_hand else list(range(T)))
            h[missing], c[missing] = 0.0, 0.0  # what pose-format stores for an undetected hand
            cols.append(h)
            confs.append(c)
        if world:  # metres about the hip centre, stored as (x * W, y * H, z)
            wl = np.stack([self.to_camera(body[n] - hip_c) for n in BODY8], 1)
            cols.append(wl * np.array([W, H, 1.0]))
            confs.append(np.full((T, 8), 0.9))
        data = np.concatenate(cols, 1)[:, None].repeat(people, 1).astype(np.float32)
        conf = np.concatenate(confs, 1)[:, None].repeat(people, 1).astype(np.float32)
        for (t, p), v in (conf_overrides or {}).items():
            conf[t, :, p] = v
        for (t, p), v in (data_overrides or {}).items():
            data[t, :, p] = v
        pose = Pose(header, NumPyPoseBody(fps, data, conf))
        with open(path, "wb") as f:
            pose.write(f)
        return body, hands


@pytest.fixture(scope="session")
def pose_files() -> PoseFiles:
    """``pose_files.write(path, T=40, ...)`` -> ``(body, hands)`` truth; its constants and frames for checks."""
    pytest.importorskip("pose_format")
    return PoseFiles()


# ----------------------------------------------------------------------------- round trips on a robot
def _random_feasible_pose(robot, n: int, seed: int, margin: float = 0.15, tries: int = 50) -> torch.Tensor:
    """``(n, n_joints)`` random angles inside the limits, shrunk by ``margin`` of each
    range, without self-collision (pairs at least their d_min apart)."""
    gen = torch.Generator().manual_seed(seed)
    lo, hi = robot.lower_limits, robot.upper_limits
    out = []
    for _ in range(tries):
        u = torch.rand(4 * n, robot.n_joints, generator=gen, dtype=torch.float64).to(lo.dtype)
        q = lo + (hi - lo) * (margin + (1 - 2 * margin) * u)
        d = robot.capsule_distances(robot.forward_kinematics(q))
        ok = (d >= robot.collision_margins).all(-1)
        out.extend(q[ok])
        if len(out) >= n:
            return torch.stack(out[:n])
    raise RuntimeError(f"no collision-free pose of {robot.name} found")


def _demonstration_from_robot(robot, q: torch.Tensor, fps: float = 15.0) -> Demonstration:
    """A demonstration whose every target the robot meets exactly at ``q`` (T, n)."""
    with torch.no_grad():
        pts = robot_points(robot, robot.forward_kinematics(q))
    T = q.shape[0]
    arm = torch.stack([pts["shoulder"], pts["elbow"], pts["wrist"]], dim=2).double().numpy()  # (T, 2, 3, 3)
    fingers = np.full((T, 2, 5, 2, 3), np.nan)
    fmask = np.zeros((T, 2, 5), dtype=bool)
    if robot.has_fingers:
        k = 0
        for s, side in enumerate(SIDES):
            arm_spec = robot.arm(side)
            for f, name in enumerate(FINGERS):
                if arm_spec.fingers and name in arm_spec.fingers:
                    fingers[:, s, f, 0] = pts["finger_base"][:, k].double().numpy()
                    fingers[:, s, f, 1] = pts["finger_tip"][:, k].double().numpy()
                    fmask[:, s, f] = True
                    k += 1
    return Demonstration(
        fps=fps,
        arm_positions=arm,
        arm_mask=np.ones((T, 2, 3), dtype=bool),
        wrist_rotations=pts["wrist_rotation"].double().numpy(),
        wrist_mask=np.ones((T, 2), dtype=bool),
        finger_positions=fingers,
        finger_mask=fmask,
        name=f"{robot.name}-pose",
    )


@pytest.fixture(scope="session")
def random_feasible_pose() -> Callable[..., torch.Tensor]:
    """``random_feasible_pose(robot, n, seed, margin=0.15)``: ``(n, n_joints)`` inside the limits, collision-free."""
    return _random_feasible_pose


@pytest.fixture(scope="session")
def demonstration_from_robot() -> Callable[..., Demonstration]:
    """``demonstration_from_robot(robot, q, fps=15.0)``: every target the robot meets exactly at ``q``."""
    return _demonstration_from_robot


# ----------------------------------------------------------------------------- the command line
def _assert_one_line_error(code, err, *needles):
    """``code`` is 2 and ``err`` is one non-empty line, no traceback, holding every one of ``needles``."""
    assert code == 2
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for needle in needles:
        assert needle in lines[0], (needle, lines[0])


@pytest.fixture(scope="session")
def assert_one_line_error() -> Callable[..., None]:
    """``assert_one_line_error(code, err, *needles)``: exit status 2, one stderr line holding the needles, no traceback."""
    return _assert_one_line_error


@pytest.fixture
def work(tmp_path, monkeypatch) -> Path:
    """A folder of its own as the current folder (outputs of relative paths land in it)."""
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.fixture
def demo_npz(work, make_demo) -> Path:
    """``work/demo.npz``: a 12-frame demonstration at 10 fps."""
    from nlo_lab.human import save_npz

    return save_npz(make_demo(T=12, fps=10.0), work / "demo.npz")


@pytest.fixture
def others_folder(tmp_path) -> Path:
    """A folder another user owns: made and handed to uid 65534 as root, else root's ``/usr``."""
    if os.geteuid() == 0:
        theirs = tmp_path / "theirs"
        theirs.mkdir(mode=0o777)
        os.chown(theirs, 65534, 65534)
        return theirs
    return Path("/usr")  # root's, whatever the test user


@pytest.fixture
def nan_loss(monkeypatch) -> None:
    """The pipeline's latent optimisation runs as usual, then reports a NaN loss (as absurd weights would)."""
    import nlo_lab.pipeline as pipeline

    real = pipeline.optimize_latent

    def optimize_latent(*args, **kwargs):
        result = real(*args, **kwargs)
        result.loss = torch.full_like(result.loss, float("nan"))
        return result

    monkeypatch.setattr(pipeline, "optimize_latent", optimize_latent)
