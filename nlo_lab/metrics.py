"""Tracking and feasibility metrics (docs/DESIGN.md, "Metric").

* :func:`frechet_distance`: exact discrete Fréchet distance, computed along
  anti-diagonals of the coupling table with numpy (every cell of an
  anti-diagonal depends only on the two previous anti-diagonals), so the Python
  loop runs ``n + m - 1`` times instead of ``n * m``, and memory is linear:
  three diagonals and the distances of one, never the ``n x m`` table.
* :func:`velocity_error` / :func:`acceleration_error`: mean norm of the
  difference of finite-difference derivatives.
* :func:`tracking_errors`: wrist and elbow Fréchet distances after mapping the
  human into the robot's frame, plus velocity and acceleration errors.
* :func:`self_collision_frames`, :func:`limit_violations`: feasibility counts.
* :func:`velocity_violations`, :func:`max_joint_speed_ratio`, :func:`max_joint_step`:
  joint speed against the robot's published velocity limits, on a trajectory's own
  time base (a retimed trajectory's samples are not ``1/fps`` apart), on
  :func:`joint_speeds` and :func:`speed_ratios` (at home in :mod:`nlo_lab.robot.speeds`:
  retiming reads them too; here for the metrics' readers).

The metrics measure a trajectory; they come after inference on the data's path and import
nothing of it. The retargeting summary (:func:`nlo_lab.pipeline.summary`) reports them
(docs/ARCHITECTURE.md, "The order").
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from nlo_lab.errors import SettingsError
from nlo_lab.human import map_to_robot
from nlo_lab.human.demonstration import SIDES
from nlo_lab.robot import check_angles
from nlo_lab.robot.speeds import joint_speeds, speed_ratios
from nlo_lab.settings import check_array, check_positive

if TYPE_CHECKING:  # pragma: no cover
    from nlo_lab.human import Demonstration
    from nlo_lab.robot import Robot

__all__ = [
    "frechet_distance",
    "frechet_distance_reference",
    "velocity_error",
    "acceleration_error",
    "tracking_errors",
    "self_collision_frames",
    "limit_violations",
    "joint_speeds",
    "speed_ratios",
    "joint_speed_ratios",
    "velocity_violations",
    "max_joint_speed_ratio",
    "max_joint_step",
]



_BAND = 64  # anti-diagonals whose distances frechet_distance computes in one numpy pass
# Frames per forward-kinematics batch of the robot-side metrics: every link's pose and every capsule pair's
# intermediates of a whole recording at once took 150 kB a frame on YuMi (20,000 frames: 3.8 GB); in chunks
# the memory stays that of one chunk, whatever the recording's length. 250, not 1000: with YuMi's 873 capsule
# pairs (the refit) a 1000-frame chunk's distances lifted a long recording's resident memory by some 450 MB,
# the peak of the whole retargeting (2026-11-26, benchmarks/reliability.py's recording).
METRIC_CHUNK_FRAMES = 250


def _curve(x: Any, name: str) -> np.ndarray:
    """A ``(n, d)`` float64 point sequence, finite, n >= 1."""
    a = check_array(name, x)
    if a.ndim == 1:
        a = a[:, None]
    if a.ndim != 2 or a.shape[0] == 0:
        raise SettingsError(f"{name} must be a non-empty (n, d) point sequence, got shape {np.shape(x)}")
    if not np.isfinite(a).all():
        row = int(np.argwhere(~np.isfinite(a))[0][0])
        raise SettingsError(f"{name} holds NaN or inf at point {row}")
    return a


def _pair(P: Any, Q: Any) -> tuple[np.ndarray, np.ndarray]:
    p, q = _curve(P, "P"), _curve(Q, "Q")
    if p.shape[1] != q.shape[1]:
        raise SettingsError(f"P and Q must have the same point dimension, got {p.shape[1]} and {q.shape[1]}")
    return p, q


def frechet_distance_reference(P: Any, Q: Any) -> float:
    """Discrete Fréchet distance by the textbook dynamic programme (pure Python).

    Slow (a double loop over ``n * m`` cells); kept as the reference the fast
    version is tested against, and as the benchmark's baseline.

    Args:
        P: ``(n, d)`` points.
        Q: ``(m, d)`` points.

    Returns:
        The distance, in the points' unit.
    """
    p, q = _pair(P, Q)
    pl, ql = p.tolist(), q.tolist()
    n, m = len(pl), len(ql)
    inf = math.inf
    prev = [inf] * m  # row i - 1 of the coupling table
    for i in range(n):
        cur = [inf] * m
        pi = pl[i]
        for j in range(m):
            d = math.dist(pi, ql[j])
            if i == 0 and j == 0:
                best = d
            else:
                best = min(prev[j], prev[j - 1] if j > 0 else inf, cur[j - 1] if j > 0 else inf)
            cur[j] = d if d > best else best
        prev = cur
    return float(prev[m - 1])


def frechet_distance(P: Any, Q: Any) -> float:
    """Exact discrete Fréchet distance between two point sequences (fast).

    ``c[i, j] = max(d(P_i, Q_j), min(c[i-1, j], c[i-1, j-1], c[i, j-1]))``
    evaluated one anti-diagonal ``k = i + j`` at a time with numpy.

    Args:
        P: ``(n, d)`` points (e.g. ``(n, 3)`` [m]).
        Q: ``(m, d)`` points.

    Returns:
        The distance, in the points' unit.

    Raises:
        NloLabError: empty, non-finite or mismatched inputs.
    """
    p, q = _pair(P, Q)
    if p.shape[0] > q.shape[0]:  # shorter curve on the rows: shorter diagonals
        p, q = q, p
    n, m = p.shape[0], q.shape[0]
    if n == 1 or m == 1:
        diff = p[:, None, :] - q[None, :, :]
        return float(math.sqrt(np.einsum("ijc,ijc->ij", diff, diff).max()))
    # Squared distances for a block of _BAND anti-diagonals at a time (never the (n, m)
    # table: memory is linear in n + m); max/min commute with the monotone sqrt, taken once.
    # Cell (i, k - i) pairs p[i] with q_rev[m - 1 - k + i]; q_rev is padded so that the
    # cells outside the table index harmless zeros (they are never read).
    pad = n + _BAND
    q_rev = np.zeros((p.shape[1], m + 2 * pad))  # per coordinate, contiguous
    q_rev[:, pad: pad + m] = q[::-1].T
    p_cols = np.ascontiguousarray(p.T)
    inf = np.inf
    # Three rotating buffers over rows, padded at index 0 with the row "-1" (inf).
    prev2 = np.full(n + 1, inf)
    prev2[0] = 0.0  # lets cell (0, 0) start the recursion at k = 0
    prev1 = np.full(n + 1, inf)
    cur = np.full(n + 1, inf)
    tmp = np.empty(n)
    for k0 in range(0, n + m - 1, _BAND):
        k1 = min(k0 + _BAND, n + m - 1)  # diagonals k0 .. k1 - 1
        r0, r1 = max(0, k0 - m + 1), min(n - 1, k1 - 1)  # rows any of them touches
        R = r1 - r0 + 1
        first, last = pad + m - 1 - k0 + r0, pad + m - 1 - (k1 - 1) + r0  # q_rev start of diagonal k0, k1 - 1
        block = np.zeros((k1 - k0, R))  # (B, R) squared distances
        for c in range(p.shape[1]):  # per coordinate: no (B, R, d) temporary
            windows = np.lib.stride_tricks.sliding_window_view(q_rev[c, last: first + R], R)[::-1]  # (B, R) views
            diff = p_cols[c, r0: r1 + 1][None, :] - windows
            diff *= diff
            block += diff
        for k in range(k0, k1):
            lo = k - m + 1 if k >= m else 0
            hi = k if k < n else n - 1
            dk = block[k - k0, lo - r0: hi - r0 + 1]
            t = tmp[: hi - lo + 1]
            np.minimum(prev1[lo: hi + 1], prev1[lo + 1: hi + 2], out=t)  # up, left
            np.minimum(t, prev2[lo: hi + 1], out=t)  # diagonal
            np.maximum(dk, t, out=cur[lo + 1: hi + 2])
            if k == 0:
                prev2[0] = inf
            prev2, prev1, cur = prev1, cur, prev2
    return float(math.sqrt(prev1[n]))


def _derivative_error(a: Any, b: Any, fps: float, order: int, name: str) -> float:
    x = check_array(f"{name}: a", a)
    y = check_array(f"{name}: b", b)
    if x.shape != y.shape:
        raise SettingsError(f"{name}: a and b must have the same shape, got {x.shape} and {y.shape}")
    if x.ndim < 2:
        raise SettingsError(f"{name}: expected (T, ..., d) trajectories, got shape {x.shape}")
    rate = check_positive(f"{name}: fps", fps)
    if x.shape[0] <= order:
        raise SettingsError(f"{name}: needs more than {order} frames, got {x.shape[0]}")
    dx = np.diff(x, n=order, axis=0) * rate**order  # (T - order, ..., d)
    dy = np.diff(y, n=order, axis=0) * rate**order
    err = np.linalg.norm(dx - dy, axis=-1)  # NaN where a point is masked
    err = err[np.isfinite(err)]
    return float(err.mean()) if err.size else float("nan")


def velocity_error(a: Any, b: Any, fps: float) -> float:
    """Mean norm of the velocity difference between two trajectories.

    Args:
        a: ``(T, ..., d)`` positions [m]; NaN marks a missing point.
        b: same shape as ``a``.
        fps: frames per second (> 0).

    Returns:
        Mean over frames and points of ``|v_a - v_b|`` [m/s]; velocities are
        forward differences times ``fps``. Entries touching a NaN are skipped
        (NaN if none is left).
    """
    return _derivative_error(a, b, fps, 1, "velocity_error")


def acceleration_error(a: Any, b: Any, fps: float) -> float:
    """Mean norm of the acceleration difference (second differences times ``fps²``) [m/s²].

    Args and NaN handling as :func:`velocity_error`.
    """
    return _derivative_error(a, b, fps, 2, "acceleration_error")


# ----------------------------------------------------------------- robot side
def _angles(robot, angles: Any) -> np.ndarray:
    return check_angles(angles, robot.n_joints, robot.name, getattr(robot, "joint_names", None))  # (T, n) float64


def _as_tensor(robot, q: np.ndarray):
    """``(T, n)`` angles as a tensor in the robot's dtype and on its device."""
    # lazy: torch: the command line's --help and bad flags do not wait for it
    import torch

    ref = robot.lower_limits
    return torch.tensor(q, dtype=ref.dtype, device=ref.device)  # a copy: angles read from a file may be read-only


def _poses_torch(robot, q: np.ndarray):
    """FK of ``(T, n)`` angles in the robot's dtype and device: link -> ``(T, 4, 4)`` tensors."""
    import torch  # lazy, as in _as_tensor

    with torch.no_grad():
        return robot.forward_kinematics(_as_tensor(robot, q))


def _chunks(frames: int):
    """Row slices of at most :data:`METRIC_CHUNK_FRAMES` frames covering ``frames``."""
    return (slice(start, min(start + METRIC_CHUNK_FRAMES, frames)) for start in range(0, frames, METRIC_CHUNK_FRAMES))


def _forward(robot, q: np.ndarray) -> dict[str, np.ndarray]:
    """FK as numpy: link -> ``(T, 4, 4)`` float64."""
    return {k: v.detach().cpu().double().numpy() for k, v in _poses_torch(robot, q).items()}


def _mapped_human(demo: Demonstration, robot) -> np.ndarray:
    mapped = np.asarray(map_to_robot(demo, robot), dtype=np.float64)
    if mapped.shape != (len(demo), 2, 3, 3):
        raise SettingsError(f"map_to_robot returned shape {mapped.shape}, expected {(len(demo), 2, 3, 3)}")
    return mapped


def tracking_errors(demo: Demonstration, robot: Robot, angles: Any) -> dict[str, float]:
    """Tracking error of a robot trajectory against a human demonstration.

    Args:
        demo: the human demonstration (``T`` frames).
        robot: a ``nlo_lab.robot.Robot``.
        angles: ``(T, n_joints)`` joint angles [rad].

    Returns:
        ``frechet_wrist_m`` and ``frechet_elbow_m`` (each averaged over the arms
        that are observed), ``frechet_m`` (their mean), ``velocity_error``
        [m/s] and ``acceleration_error`` [m/s²] over wrists and elbows of both
        arms. Frames where a human point is masked are dropped from that curve.
    """
    q = _angles(robot, angles)
    if q.shape[0] != len(demo):
        raise SettingsError(f"angles have {q.shape[0]} frames but the demonstration {demo.name!r} has {len(demo)}")
    human = _mapped_human(demo, robot)  # (T, 2, 3, 3): side x (shoulder, elbow, wrist)
    robot_pts = np.empty((q.shape[0], 2, 2, 3))  # (T, side, (elbow, wrist), 3) [m]
    for rows in _chunks(q.shape[0]):
        poses = _forward(robot, q[rows])
        for s, side in enumerate(SIDES):
            arm = robot.arm(side)
            robot_pts[rows, s, 0] = poses[arm.elbow][:, :3, 3]
            robot_pts[rows, s, 1] = poses[arm.wrist][:, :3, 3]
    human_pts = human[:, :, 1:].copy()  # (T, 2, 2, 3)
    human_pts[~demo.arm_mask[:, :, 1:]] = np.nan
    per_point: dict[str, list[float]] = {"elbow": [], "wrist": []}
    for s in range(2):
        for j, joint in enumerate(("elbow", "wrist")):
            h = human_pts[:, s, j]
            valid = np.isfinite(h).all(-1)
            if valid.sum() == 0:
                continue
            per_point[joint].append(frechet_distance(h[valid], robot_pts[valid, s, j]))
    if not per_point["wrist"] or not per_point["elbow"]:
        raise SettingsError(f"demonstration {demo.name!r} has no observed elbow or wrist on either arm")
    wrist = float(np.mean(per_point["wrist"]))
    elbow = float(np.mean(per_point["elbow"]))
    return {
        "frechet_wrist_m": wrist,
        "frechet_elbow_m": elbow,
        "frechet_m": 0.5 * (wrist + elbow),
        "velocity_error": velocity_error(human_pts, robot_pts, demo.fps) if len(demo) > 1 else float("nan"),
        "acceleration_error": acceleration_error(human_pts, robot_pts, demo.fps) if len(demo) > 2 else float("nan"),
    }


def self_collision_frames(robot: Robot, angles: Any, cull: bool = False) -> int:
    """Number of frames where any checked capsule pair penetrates (distance < 0).

    Args:
        robot: a ``nlo_lab.robot.Robot``.
        angles: ``(T, n_joints)`` [rad].
        cull: the faster form with the same verdicts (:func:`nlo_lab.objective.penetration.penetrating`: the capsules'
            ends from the objective's point plan, a pair measured exactly only where a bound does not clear it; YuMi,
            the 170 frames of a real recording: 3.4 against 28 ms). The retargeting summary takes it with the fast paths.
    """
    q = _angles(robot, angles)
    if cull:
        from nlo_lab.objective.penetration import penetrating  # lazy: it imports torch

        return sum(int(penetrating(robot, _as_tensor(robot, q[rows]), cull=True).sum()) for rows in _chunks(q.shape[0]))
    # lazy: torch: the command line's --help and bad flags do not wait for it
    import torch

    colliding = 0
    for rows in _chunks(q.shape[0]):
        with torch.no_grad():
            d = robot.capsule_distances(_poses_torch(robot, q[rows]))  # (chunk, P) [m]
        if d.numel():
            colliding += int((d < 0).any(dim=-1).sum().item())
    return colliding


def limit_violations(robot: Robot, angles: Any, tol: float = 1e-6) -> int:
    """Number of (frame, joint) entries outside the joint limits by more than ``tol``.

    Args:
        robot: anything with ``n_joints``, ``lower_limits`` and ``upper_limits`` (n,).
        angles: ``(T, n_joints)`` [rad].
        tol: slack [rad] for round-off.
    """
    q = _angles(robot, angles)
    lower = np.asarray(robot.lower_limits.detach().cpu() if hasattr(robot.lower_limits, "detach") else robot.lower_limits, dtype=np.float64)
    upper = np.asarray(robot.upper_limits.detach().cpu() if hasattr(robot.upper_limits, "detach") else robot.upper_limits, dtype=np.float64)
    return int(((q < lower - tol) | (q > upper + tol)).sum())


# ----------------------------------------------------------------- joint speed
def _limits(robot) -> np.ndarray:
    v = robot.velocity_limits
    return np.asarray(v.detach().cpu() if hasattr(v, "detach") else v, dtype=np.float64)


def _times(angles: np.ndarray, times: Any, fps: float | None) -> np.ndarray:
    if times is None:
        if fps is None:
            raise SettingsError("give the trajectory's times or its fps (> 0)")
        return np.arange(angles.shape[0]) / check_positive("fps", fps)
    t = check_array("times", times)
    if t.shape != (angles.shape[0],) or not np.isfinite(t).all() or (np.diff(t) <= 0).any():
        raise SettingsError(f"times must be ({angles.shape[0]},) finite and strictly increasing")
    return t


def joint_speed_ratios(robot: Robot, angles: Any, times: Any = None, fps: float | None = None) -> np.ndarray:
    """``(T-1, n)`` finite-difference joint speed over the robot's velocity limit.

    Args:
        robot: anything with ``n_joints`` and ``velocity_limits`` (n,) [rad/s] (inf = none).
        angles: ``(T, n_joints)`` [rad].
        times: ``(T,)`` sample times [s] (the trajectory file's own time base), or None
            with ``fps`` for frames ``1/fps`` apart.
    """
    q = _angles(robot, angles)
    return speed_ratios(q, _times(q, times, fps), _limits(robot))


def velocity_violations(robot: Robot, angles: Any, times: Any = None, fps: float | None = None) -> int:
    """Number of (frame pair, joint) entries faster than the joint's velocity limit
    (finite differences on ``times``, or on frames ``1/fps`` apart)."""
    return int((joint_speed_ratios(robot, angles, times, fps) > 1.0).sum())


def max_joint_speed_ratio(robot: Robot, angles: Any, times: Any = None, fps: float | None = None) -> float:
    """Largest joint speed over its limit (1 = at the limit; 0 for a single frame)."""
    r = joint_speed_ratios(robot, angles, times, fps)
    return float(r.max()) if r.size else 0.0


def max_joint_step(angles: Any) -> float:
    """Largest change of any joint between consecutive samples [rad] (0 for one frame)."""
    q = check_array("angles", angles)
    if q.ndim != 2 or not np.isfinite(q).all():
        raise SettingsError(f"angles must be (T, n) finite joint angles, got shape {q.shape}")
    return float(np.abs(np.diff(q, axis=0)).max()) if len(q) > 1 and q.shape[1] else 0.0
