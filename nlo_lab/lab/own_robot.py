"""Cell helpers of notebook 10, "Your own robot": the lesson robot, and specs changed one field at a time.

:func:`lesson_urdf` is the URDF shipped for the lesson (``assets/robots/lesson``, written by
nlo_lab, meshes made with trimesh). :func:`spec_variant` writes a copy of a spec with some fields
changed into the notebook's work folder and loads it, so a cell can show what a field changes.
"""

from __future__ import annotations

import copy
import json
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import torch

from nlo_lab.paths import ROBOTS_DIR
from nlo_lab.robot import Robot, load_robot
from nlo_lab.robot.spec import spec_text
from nlo_lab.settings import LATENT_ITERATIONS

__all__ = ["LESSON_URDF", "lesson_urdf", "spec_variant", "retarget_report"]

LESSON_URDF = ROBOTS_DIR / "lesson" / "lesson_robot.urdf"


def lesson_urdf() -> Path:
    """The lesson robot's URDF (a pedestal, a torso, two 6-joint arms, 3-finger hands; mesh files)."""
    return LESSON_URDF


def spec_variant(spec: str | os.PathLike, name: str, edit: Callable[[dict], None]) -> Robot:
    """The robot of a copy of ``spec`` changed by ``edit(data)`` (the spec's JSON data, edited in place).

    The copy is written beside ``spec`` as ``NAME.json`` (its ``urdf`` and ``srdf`` fields stay
    right: the folder is the same), then loaded: a change the URDF does not allow is refused there.
    """
    spec = Path(spec)
    data = json.loads(spec.read_text(encoding="utf-8"))
    changed = copy.deepcopy(data)
    edit(changed)
    path = spec.with_name(f"{name}.json")
    path.write_text(spec_text(changed), encoding="utf-8")
    return load_robot(path)


def retarget_report(robot: Robot, demo, model, iterations: int = LATENT_ITERATIONS) -> dict[str, float]:
    """Retarget ``demo`` with ``model`` and measure what a spec's fields change (one table row):

    ``direction_deg`` (the arms' direction error, :func:`nlo_lab.evaluation.direction_error`),
    ``hand_deg`` (the mean angle between the robot's hand frame and the human's wrist frame),
    ``frechet_m``, ``slowdown`` (the retimed output's duration over the recording's), and
    ``arms_gap_m`` (the smallest gap between a left-arm and a right-arm capsule of the checked pairs, over the output).
    """
    from nlo_lab.evaluation import direction_error
    from nlo_lab.inference import OptimizeSettings
    from nlo_lab.objective import robot_points
    from nlo_lab.pipeline import retarget

    result = retarget(demo, robot, model=model, settings=OptimizeSettings(iterations=iterations))
    q = torch.as_tensor(np.array(result.trajectory.angles, dtype=np.float64))
    r64 = robot.to(dtype=torch.float64)
    with torch.no_grad():
        poses = r64.forward_kinematics(q)
        gaps = r64.capsule_distances(poses)  # (T, P)
        rotation = robot_points(r64, poses)["wrist_rotation"].numpy()  # (T, 2, 3, 3) R_wrist R_align
    left, right = (set(robot.model.subtree(robot.arm(side).shoulder)) for side in ("left", "right"))
    link = {c.name: c.link for c in robot.spec.capsules}
    between = [k for k, (a, b) in enumerate(robot.spec.collision_pairs)
               if (link[a] in left and link[b] in right) or (link[a] in right and link[b] in left)]
    arms_gap = float(gaps[:, between].min()) if between else float("nan")
    human, seen = demo.wrist_rotations, demo.wrist_mask
    cos = (np.einsum("tsij,tsij->ts", rotation, np.nan_to_num(human)) - 1) / 2
    hand = np.degrees(np.arccos(np.clip(cos[seen], -1, 1))).mean() if seen.any() else float("nan")
    return {
        "direction_deg": direction_error(robot, demo, q.numpy())["mean_deg"],
        "hand_deg": float(hand),
        "frechet_m": float(result.summary["frechet_m"]),
        "slowdown": float(result.summary["slowdown"]),
        "arms_gap_m": arms_gap,
    }
