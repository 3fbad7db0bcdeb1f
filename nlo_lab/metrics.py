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
* :func:`hand_scores`, :func:`hand_summary`: handshape measures, how well a robot hand takes the shape of
  the human hand (below).
* :func:`velocity_violations`, :func:`max_joint_speed_ratio`, :func:`max_joint_step`:
  joint speed against the robot's published velocity limits, on a trajectory's own
  time base (a retimed trajectory's samples are not ``1/fps`` apart), on
  :func:`joint_speeds` and :func:`speed_ratios` (at home in :mod:`nlo_lab.robot.speeds`:
  retiming reads them too; here for the metrics' readers).

**Handshape measures.** One scorer for any method's joint angles (``benchmarks/hands.py`` scores nlo_lab
and dex-retargeting with it; notebook 12 each handshape of its gallery; the retargeting summary its means).
Everything is compared in the wrist frame (the human's ``R_body_wrist``; the robot's wrist link turned by
the spec's ``wrist_alignment``), so the measures see the handshape alone, not where the arm put the hand.
A **hand-frame** is one hand in one frame where the demonstration observed the wrist frame and
all five fingers (base and tip). Directions are unit vectors; an angle is
``atan2(|u × û|, u · û)`` in degrees. Per hand-frame:

* ``tip``: wrist -> fingertip direction error, mean over the five fingers (``tip_fingers``: each finger's,
  thumb .. little; :meth:`HandScores.tip_per_finger` their means over a set of hand-frames);
* ``thumb``: thumb tip -> fingertip direction error, mean over the four other fingers;
* ``finger``: finger base (knuckle; thumb: its metacarpophalangeal joint) -> tip direction
  error, mean over the five fingers;
* ``pinch_human``, ``pinch_robot``: thumb tip -> index tip distance in hand lengths (the mean
  wrist -> knuckle distance of the four fingers: the demonstrator's median over the recording,
  the robot's at its reference pose).

Over a set of hand-frames (:meth:`HandScores.summary`): the three angles averaged, and the
**pinch correlation**, Pearson's r of ``pinch_human`` against ``pinch_robot``.

The metrics measure a trajectory; they come after inference on the data's path and import
nothing of it. The retargeting summary (:func:`nlo_lab.pipeline.summary`) reports them
(docs/ARCHITECTURE.md, "The order").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.human import map_to_robot
from nlo_lab.human.demonstration import FINGERS, SIDES
from nlo_lab.objective import point_plan, targets_from_demonstration
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
    "MEASURES",
    "HAND_KEYS",
    "HandScores",
    "angle_deg",
    "hand_frames_mask",
    "hand_scores",
    "hand_summary",
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


# ---- handshape measures (the module's docstring defines them) ----

MEASURES = ("tip", "thumb", "finger", "pinch")  # the summary's keys: tip_deg, thumb_deg, finger_deg, pinch_r


def angle_deg(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle between the vectors ``u, v (..., 3)`` in degrees, ``(...)`` (0 where either is zero)."""
    return np.degrees(np.arctan2(np.linalg.norm(np.cross(u, v), axis=-1), (u * v).sum(-1)))


@dataclass
class HandScores:
    """Per hand-frame measures (N hand-frames), see the module's docstring.

    Attributes:
        tip, thumb, finger: ``(N,)`` [deg].
        pinch_human, pinch_robot: ``(N,)`` [hand lengths].
        side: ``(N,)`` 0 left, 1 right; frame: ``(N,)`` the frame index.
        tip_fingers: ``(N, 5)`` [deg] the wrist -> fingertip direction error of each finger (thumb .. little, the
            demonstration's ``FINGERS``); ``tip`` is its mean over the fingers.
    """

    tip: np.ndarray
    thumb: np.ndarray
    finger: np.ndarray
    pinch_human: np.ndarray
    pinch_robot: np.ndarray
    side: np.ndarray
    frame: np.ndarray
    tip_fingers: np.ndarray

    def __len__(self) -> int:
        return int(self.tip.shape[0])

    @staticmethod
    def cat(items: list[HandScores]) -> HandScores:
        """Pool several recordings' hand-frames."""
        return HandScores(**{f.name: np.concatenate([getattr(s, f.name) for s in items]) for f in fields(HandScores)})

    def pinch_correlation(self) -> float:
        """Pearson's r of the human's and the robot's thumb-index distance (NaN below 3 hand-frames or without variation)."""
        a, b = self.pinch_human, self.pinch_robot
        if len(a) < 3 or a.std() == 0 or b.std() == 0:
            return float("nan")
        return float(np.corrcoef(a, b)[0, 1])

    def tip_per_finger(self) -> np.ndarray:
        """``(5,)`` [deg] each finger's wrist -> fingertip direction error, mean over the hand-frames (NaN without any)."""
        return self.tip_fingers.mean(0) if len(self) else np.full(len(FINGERS), np.nan)

    def summary(self) -> dict[str, float]:
        """``hand_frames``, ``tip_deg``, ``thumb_deg``, ``finger_deg`` (means) and ``pinch_r``."""
        mean = lambda a: float(a.mean()) if len(a) else float("nan")  # noqa: E731
        return {"hand_frames": len(self), "tip_deg": mean(self.tip), "thumb_deg": mean(self.thumb),
                "finger_deg": mean(self.finger), "pinch_r": self.pinch_correlation()}


def hand_frames_mask(demo: Demonstration) -> np.ndarray:
    """``(T, 2)`` bool: the hand-frames (wrist frame, wrist and all five fingers observed)."""
    return demo.wrist_mask & demo.arm_mask[:, :, 2] & demo.finger_mask.all(-1)


def _robot_hand(robot, q: np.ndarray) -> dict[str, np.ndarray]:
    """The robot's wrist, wrist frame, finger bases and tips (all five per side) for ``q (T, n)``, mapped
    :data:`METRIC_CHUNK_FRAMES` frames at a time (the point plan of 20,000 YuMi frames at once raised the peak
    memory by 1.8 GB)."""
    plan = point_plan(robot, torch.float64)
    side, finger = plan.finger_side.numpy(), plan.finger_index.numpy()
    T = q.shape[0]
    wrist, rotation = np.full((T, 2, 3), np.nan), np.full((T, 2, 3, 3), np.nan)
    base, tip = np.full((T, 2, 5, 3), np.nan), np.full((T, 2, 5, 3), np.nan)
    for rows in _chunks(T):
        with torch.no_grad():
            p = plan(torch.as_tensor(np.array(q[rows], dtype=np.float64)))  # a copy: q may be read-only
        wrist[rows], rotation[rows] = p.wrist.numpy(), p.wrist_rotation.numpy()
        base[rows, side, finger] = p.finger_base.numpy()
        tip[rows, side, finger] = p.finger_tip.numpy()
    return {"wrist": wrist, "rotation": rotation, "base": base, "tip": tip, "length": plan.hand_length.numpy()}


def _why_unscorable(robot: Robot) -> str:
    """Why the hand measures cannot score ``robot``'s hands ("" if they can: five fingers a side)."""
    if not robot.has_fingers:
        return f"{robot.name} has no fingers: there is no handshape to score"
    fingers_of = {name for arm in robot.spec.arms.values() for name in (arm.fingers or {})}
    if fingers_of != set(FINGERS):
        return f"{robot.name}: the hand measures need all five fingers, the spec names {sorted(fingers_of)}"
    return ""


def hand_scores(robot: Robot, q, demo: Demonstration) -> HandScores:
    """Score the robot's hands at ``q (T, n)`` [rad] against the demonstration's (T frames).

    Raises:
        SettingsError: the robot has no fingers, or ``q`` does not fit the robot or the demonstration.
    """
    q = np.asarray(q, dtype=np.float64)
    unscorable = _why_unscorable(robot)
    if unscorable:
        raise SettingsError(unscorable)
    if q.ndim != 2 or q.shape != (len(demo), robot.n_joints):
        raise SettingsError(f"joint angles of shape {q.shape} do not fit {len(demo)} frames x {robot.n_joints} joints")
    h_len = targets_from_demonstration(demo, dtype=torch.float64).hand_length[0].numpy()  # (2,)
    mask = hand_frames_mask(demo)
    frames, sides = np.nonzero(mask)
    seen = np.nonzero(mask.any(1))[0]  # the robot's hands mapped in the frames with a hand-frame only
    r = _robot_hand(robot, q[seen])
    row = np.searchsorted(seen, frames)  # each hand-frame's row in r

    def wrist_frame(points, wrist, rotation):  # (N, k, 3) in the wrist frame
        return np.einsum("nji,nkj->nki", rotation, points - wrist[:, None])

    def pick(x):
        return x[frames, sides]

    human_base = wrist_frame(pick(demo.finger_positions[:, :, :, 0]), pick(demo.arm_positions[:, :, 2]), pick(demo.wrist_rotations))
    human_tip = wrist_frame(pick(demo.finger_positions[:, :, :, 1]), pick(demo.arm_positions[:, :, 2]), pick(demo.wrist_rotations))
    def pick_robot(x):
        return x[row, sides]

    robot_base = wrist_frame(pick_robot(r["base"]), pick_robot(r["wrist"]), pick_robot(r["rotation"]))
    robot_tip = wrist_frame(pick_robot(r["tip"]), pick_robot(r["wrist"]), pick_robot(r["rotation"]))
    tip_fingers = angle_deg(robot_tip, human_tip)  # (N, 5)
    return HandScores(
        tip=tip_fingers.mean(-1),
        thumb=angle_deg(robot_tip[:, 1:] - robot_tip[:, :1], human_tip[:, 1:] - human_tip[:, :1]).mean(-1),
        finger=angle_deg(robot_tip - robot_base, human_tip - human_base).mean(-1),
        pinch_human=np.linalg.norm(human_tip[:, 1] - human_tip[:, 0], axis=-1) / h_len[sides],
        pinch_robot=np.linalg.norm(robot_tip[:, 1] - robot_tip[:, 0], axis=-1) / r["length"][sides],
        side=sides.astype(np.int64),
        frame=frames.astype(np.int64),
        tip_fingers=tip_fingers,
    )


# the retargeting summary's hand keys (nlo_lab.pipeline.summary; README, "Command line"): HandScores.summary's
HAND_KEYS = ("hand_frames", "wrist_tip_deg", "thumb_tips_deg", "base_tip_deg", "pinch_r")


def hand_summary(robot: Robot, angles: Any, demo: Demonstration) -> dict[str, Any]:
    """:data:`HAND_KEYS` of ``angles (T, n)`` against ``demo``: the hand-frames' count and the means of
    :func:`hand_scores` (``wrist_tip_deg``: ``tip``, ``thumb_tips_deg``: ``thumb``, ``base_tip_deg``: ``finger``,
    ``pinch_r``: the pinch correlation). All None on a robot whose hands cannot be scored (no fingers, or not all
    five); the measures None without a hand-frame (``pinch_r`` below 3, or without variation)."""
    if _why_unscorable(robot):
        return dict.fromkeys(HAND_KEYS)
    s = hand_scores(robot, _angles(robot, angles), demo).summary()

    def finite(x: float) -> float | None:
        return float(x) if math.isfinite(x) else None

    return {"hand_frames": int(s["hand_frames"]), "wrist_tip_deg": finite(s["tip_deg"]), "thumb_tips_deg": finite(s["thumb_deg"]),
            "base_tip_deg": finite(s["finger_deg"]), "pinch_r": finite(s["pinch_r"])}
