"""Handshape measures: how well a robot hand takes the shape of the human hand, frame by frame.

One scorer for any method's joint angles (``benchmarks/hands.py`` scores nlo_lab and
dex-retargeting with it; notebook 12 each handshape of its gallery). Everything is compared in
the wrist frame (the human's ``R_body_wrist``; the robot's wrist link turned by the spec's
``wrist_alignment``), so the measures see the handshape alone, not where the arm put the hand.
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
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

import numpy as np
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.human.demonstration import FINGERS, Demonstration
from nlo_lab.objective import TERMS, LossWeights, Objective, point_plan, targets_from_demonstration

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot import Robot

__all__ = [
    "HandScores", "hand_scores", "hand_frames_mask", "angle_deg", "MEASURES",
    "finger_chains", "hand_joint_indices", "robot_hand_points", "best_hand_angles",
]

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
    """The robot's wrist, wrist frame, finger bases and tips (all five per side) for ``q (T, n)``."""
    plan = point_plan(robot, torch.float64)
    with torch.no_grad():
        p = plan(torch.as_tensor(np.array(q, dtype=np.float64)))  # a copy: q may be read-only
    T = q.shape[0]
    base, tip = np.full((T, 2, 5, 3), np.nan), np.full((T, 2, 5, 3), np.nan)
    side, finger = plan.finger_side.numpy(), plan.finger_index.numpy()
    base[:, side, finger] = p.finger_base.numpy()
    tip[:, side, finger] = p.finger_tip.numpy()
    return {"wrist": p.wrist.numpy(), "rotation": p.wrist_rotation.numpy(), "base": base, "tip": tip,
            "length": plan.hand_length.numpy()}


def hand_scores(robot: Robot, q, demo: Demonstration) -> HandScores:
    """Score the robot's hands at ``q (T, n)`` [rad] against the demonstration's (T frames).

    Raises:
        SettingsError: the robot has no fingers, or ``q`` does not fit the robot or the demonstration.
    """
    q = np.asarray(q, dtype=np.float64)
    if not robot.has_fingers:
        raise SettingsError(f"{robot.name} has no fingers: there is no handshape to score")
    fingers_of = {name for arm in robot.spec.arms.values() for name in (arm.fingers or {})}
    if fingers_of != set(FINGERS):
        raise SettingsError(f"{robot.name}: the hand measures need all five fingers, the spec names {sorted(fingers_of)}")
    if q.ndim != 2 or q.shape != (len(demo), robot.n_joints):
        raise SettingsError(f"joint angles of shape {q.shape} do not fit {len(demo)} frames x {robot.n_joints} joints")
    r = _robot_hand(robot, q)
    h_len = targets_from_demonstration(demo, dtype=torch.float64).hand_length[0].numpy()  # (2,)
    mask = hand_frames_mask(demo)
    frames, sides = np.nonzero(mask)

    def wrist_frame(points, wrist, rotation):  # (N, k, 3) in the wrist frame
        return np.einsum("nji,nkj->nki", rotation, points - wrist[:, None])

    def pick(x):
        return x[frames, sides]

    human_base = wrist_frame(pick(demo.finger_positions[:, :, :, 0]), pick(demo.arm_positions[:, :, 2]), pick(demo.wrist_rotations))
    human_tip = wrist_frame(pick(demo.finger_positions[:, :, :, 1]), pick(demo.arm_positions[:, :, 2]), pick(demo.wrist_rotations))
    robot_base = wrist_frame(pick(r["base"]), pick(r["wrist"]), pick(r["rotation"]))
    robot_tip = wrist_frame(pick(r["tip"]), pick(r["wrist"]), pick(r["rotation"]))
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


def finger_chains(robot: Robot, side: str) -> dict[str, list[str]]:
    """Per finger of ``side``, the links from the wrist link to the fingertip link (the URDF chain)."""
    arm = robot.arm(side)
    out = {}
    for name, (_, tip) in (arm.fingers or {}).items():
        chain, link = [tip], tip
        while link != arm.wrist:
            joint = robot.model.parent_joint(link)
            if joint is None:
                raise SettingsError(f"{robot.name}: fingertip {tip!r} does not hang below the wrist link {arm.wrist!r}")
            link = joint.parent
            chain.append(link)
        out[name] = chain[::-1]
    return out


def hand_joint_indices(robot: Robot, side: str) -> list[int]:
    """Indices (into ``robot.joint_names``) of the actuated joints that move the fingers of ``side``."""
    names = set()
    for chain in finger_chains(robot, side).values():
        for link in chain[1:]:
            joint = robot.model.parent_joint(link)
            if joint.moving:
                names.add(joint.mimic[0] if joint.mimic else joint.name)
    return sorted(robot.joint_names.index(n) for n in names if n in robot.joint_names)


def robot_hand_points(robot: Robot, q, side: str) -> dict[str, np.ndarray]:
    """Per finger the chain's link origins ``(T, k, 3)`` [m] in the aligned wrist frame, for ``q (T, n)``."""
    q = torch.as_tensor(np.array(q, dtype=np.float64))
    rb = robot.to(dtype=torch.float64)
    with torch.no_grad():
        poses = rb.forward_kinematics(q)
    arm = robot.arm(side)
    wrist = poses[arm.wrist].numpy()  # (T, 4, 4)
    rot = wrist[:, :3, :3] @ arm.wrist_alignment.double().numpy()
    out = {}
    for name, chain in finger_chains(robot, side).items():
        p = np.stack([poses[link].numpy()[:, :3, 3] for link in chain], axis=1)  # (T, k, 3)
        out[name] = np.einsum("tji,tkj->tki", rot, p - wrist[:, None, :3, 3])
    return out


def best_hand_angles(robot: Robot, q, demo: Demonstration, weights=None, steps: int = 200, lr: float = 0.05) -> np.ndarray:
    """The hands' joints alone optimised on the hand terms (``tip``, ``thumb``, ``pinch`` of ``weights``),
    the arms kept at ``q (T, n)``: the closest this hand comes to each handshape (Adam in joint space,
    clamped to the limits). Returns ``(T, n)`` [rad]."""
    w = weights or LossWeights()
    only = LossWeights(**({n: 0.0 for n in TERMS} | {"latent": 0.0, "smooth": 0.0, "tip": w.tip, "thumb": w.thumb, "pinch": w.pinch}))
    rb = robot.to(dtype=torch.float64)
    loss = Objective(rb, targets_from_demonstration(demo, dtype=torch.float64), only, fused=False)
    hand = torch.zeros(robot.n_joints, dtype=torch.bool)
    hand[[i for side in ("left", "right") for i in hand_joint_indices(robot, side)]] = True
    x = torch.as_tensor(np.array(q, dtype=np.float64)).requires_grad_(True)
    opt = torch.optim.Adam([x], lr=lr)
    for _ in range(steps):
        opt.zero_grad()
        loss(x)[0].sum().backward()
        x.grad[:, ~hand] = 0.0
        opt.step()
        with torch.no_grad():
            x.copy_(torch.maximum(torch.minimum(x, rb.upper_limits), rb.lower_limits))
    return x.detach().numpy()
