"""A URDF file as a checked kinematic model: links, joints, limits and mimic rules.

yourdfpy reads the file (:func:`load_urdf`); :func:`parse_urdf` checks the tree
(one root, every joint naming existing links, no link with two parents, no
cycle, supported joint types, finite numbers) and orders links and joints
parents first. Every problem becomes one
:class:`~nlo_lab.errors.RobotDescriptionError` naming the file.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from nlo_lab.errors import RobotDescriptionError
from nlo_lab.files import as_path, check_input_file
from nlo_lab.rotations import matrix_to_rpy

__all__ = ["MOVING_TYPES", "SUPPORTED_TYPES", "MAX_URDF_BYTES", "JointInfo", "URDFModel", "load_urdf", "parse_urdf"]

MAX_URDF_BYTES = 16 << 20  # the largest URDF of example-robot-data is well under 1 MB

MOVING_TYPES = ("revolute", "continuous")
SUPPORTED_TYPES = MOVING_TYPES + ("fixed",)


# --------------------------------------------------------------------------- URDF model
@dataclass(frozen=True)
class JointInfo:
    """One URDF joint.

    Attributes:
        name: joint name.
        type: ``"revolute"``, ``"continuous"`` or ``"fixed"``.
        parent: parent link name.
        child: child link name.
        origin: ``(4, 4)`` float64 ``T_parent_joint`` (the ``<origin>``).
        axis: ``(3,)`` unit axis in the joint frame.
        lower: lower limit [rad] (``-pi`` for continuous joints without a limit).
        upper: upper limit [rad].
        mimic: ``(source_joint, multiplier, offset)`` or ``None``.
    """

    name: str
    type: str
    parent: str
    child: str
    origin: np.ndarray
    axis: np.ndarray
    lower: float
    upper: float
    mimic: tuple[str, float, float] | None = None

    @property
    def moving(self) -> bool:
        return self.type in MOVING_TYPES

    @property
    def origin_xyz_rpy(self) -> np.ndarray:
        """``(6,)`` the origin as xyz [m] + rpy [rad]."""
        return np.concatenate([self.origin[:3, 3], matrix_to_rpy(self.origin[:3, :3])])


@dataclass(frozen=True)
class URDFModel:
    """A parsed URDF: links and joints, joints in depth-first order from the root.

    Attributes:
        name: the robot's name attribute.
        path: the file it came from.
        root: the root link.
        links: link names, parents before children.
        joints: joints, parents before children.
        urdf: the ``yourdfpy.URDF`` it was built from (visuals, materials).
    """

    name: str
    path: Path
    root: str
    links: tuple[str, ...]
    joints: tuple[JointInfo, ...]
    urdf: Any = field(default=None, compare=False, repr=False)

    def joint(self, name: str) -> JointInfo:
        for j in self.joints:
            if j.name == name:
                return j
        raise RobotDescriptionError(f"{self.path}: no joint named {name!r}")

    def parent_joint(self, link: str) -> JointInfo | None:
        """The joint whose child is ``link`` (``None`` for the root)."""
        for j in self.joints:
            if j.child == link:
                return j
        return None

    def subtree(self, link: str) -> list[str]:
        """``link`` and every link below it, parents first."""
        out, found = [], {link}
        for name in self.links:  # parents come before children
            j = self.parent_joint(name)
            if name == link or (j is not None and j.parent in found):
                found.add(name)
                out.append(name)
        return out


class _LogRecorder(logging.Handler):
    """Collects what yourdfpy logs while it reads one file (it logs, not raises, on bad XML)."""

    def __init__(self) -> None:
        super().__init__(level=logging.ERROR)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


def load_urdf(path: str | Path):
    """Read a URDF file with yourdfpy (no meshes, no scene graph): the one parse of a file.

    Args:
        path: the ``.urdf`` file.

    Returns:
        The ``yourdfpy.URDF``; :func:`parse_urdf` builds the kinematic model from
        it and the viewer its visuals (``Robot.urdf``).

    Raises:
        RobotDescriptionError: a missing file or malformed XML, naming the file.
    """
    import yourdfpy  # imported here: the FK never needs it once the tree is built

    path = as_path(path)
    check_input_file(path, kind="URDF", max_bytes=MAX_URDF_BYTES, error=RobotDescriptionError)
    logger = logging.getLogger("yourdfpy")
    recorder = _LogRecorder()
    logger.addHandler(recorder)
    propagate, logger.propagate = logger.propagate, False  # its complaints become our one error
    try:
        urdf = yourdfpy.URDF.load(
            str(path), build_scene_graph=False, build_collision_scene_graph=False, load_meshes=False, load_collision_meshes=False
        )
    except Exception as exc:  # yourdfpy raises assorted types (KeyError, AttributeError, ValueError ...)
        detail = recorder.messages[0] if recorder.messages else f"{type(exc).__name__}: {exc}"
        raise RobotDescriptionError(f"{path}: malformed URDF ({detail})") from None
    finally:
        logger.removeHandler(recorder)
        logger.propagate = propagate
    if recorder.messages:  # yourdfpy recovers from broken XML; we refuse the file
        raise RobotDescriptionError(f"{path}: malformed URDF XML ({recorder.messages[0]})")
    return urdf


def _vector(value, n: int, what: str, path: Path) -> np.ndarray:
    values = np.asarray(value, dtype=np.float64).reshape(-1) if value is not None else np.zeros(n)
    if values.shape != (n,) or not np.all(np.isfinite(values)):
        raise RobotDescriptionError(f"{path}: {what} must be {n} finite numbers, got {value!r}")
    return values


def parse_urdf(path: str | Path) -> URDFModel:
    """Read a URDF file into a :class:`URDFModel` (yourdfpy parses, we check the tree).

    Args:
        path: the ``.urdf`` file.

    Returns:
        The model, joints ordered parents first; ``model.urdf`` keeps the
        ``yourdfpy.URDF`` so that nothing parses the file twice.

    Raises:
        RobotDescriptionError: missing file, malformed XML, a joint naming a link
            that does not exist, a link with two parents, several roots or a
            cycle, an unsupported joint type, a bad number, a mimic joint whose
            source does not exist.
    """
    path = as_path(path)
    urdf = load_urdf(path)
    robot = urdf.robot
    links = [link.name for link in robot.links]
    if any(n is None for n in links):
        raise RobotDescriptionError(f"{path}: a <link> has no name")
    if len(set(links)) != len(links):
        dup = sorted({n for n in links if links.count(n) > 1})
        raise RobotDescriptionError(f"{path}: duplicate link names {dup}")
    link_set = set(links)

    joints: dict[str, JointInfo] = {}
    for el in robot.joints:
        name, jtype = el.name, el.type
        if name is None:
            raise RobotDescriptionError(f"{path}: a <joint> has no name")
        if name in joints:
            raise RobotDescriptionError(f"{path}: duplicate joint name {name!r}")
        if jtype not in SUPPORTED_TYPES:
            raise RobotDescriptionError(
                f"{path}: joint {name!r} has type {jtype!r}; supported: {', '.join(SUPPORTED_TYPES)}"
            )
        for tag, link in (("parent", el.parent), ("child", el.child)):
            if link not in link_set:
                raise RobotDescriptionError(f"{path}: joint {name!r} names {tag} link {link!r}, which does not exist")
        origin = np.eye(4) if el.origin is None else np.asarray(el.origin, dtype=np.float64)
        if origin.shape != (4, 4) or not np.all(np.isfinite(origin)):
            raise RobotDescriptionError(f"{path}: joint {name!r} has a bad <origin>")
        axis = _vector(el.axis if el.axis is not None else [1.0, 0.0, 0.0], 3, f"joint {name!r} axis", path)
        lower, upper = -math.pi, math.pi
        if jtype in MOVING_TYPES:
            if np.linalg.norm(axis) < 1e-9:
                raise RobotDescriptionError(f"{path}: joint {name!r} has a zero axis")
            axis = axis / np.linalg.norm(axis)
            limit = el.limit
            if limit is None and jtype == "revolute":
                raise RobotDescriptionError(f"{path}: revolute joint {name!r} has no <limit>")
            if limit is not None and (limit.lower is not None or jtype == "revolute"):
                lower = float(_vector(limit.lower if limit.lower is not None else 0.0, 1, f"joint {name!r} lower limit", path)[0])
                upper = float(_vector(limit.upper if limit.upper is not None else 0.0, 1, f"joint {name!r} upper limit", path)[0])
            if lower > upper:
                raise RobotDescriptionError(f"{path}: joint {name!r} has lower limit {lower} > upper limit {upper}")
        mimic = None
        if el.mimic is not None:
            mult = float(_vector(el.mimic.multiplier, 1, f"joint {name!r} mimic multiplier", path)[0])
            off = float(_vector(el.mimic.offset, 1, f"joint {name!r} mimic offset", path)[0])
            mimic = (el.mimic.joint, mult, off)
        joints[name] = JointInfo(name, jtype, el.parent, el.child, origin, axis, lower, upper, mimic)

    for j in joints.values():
        if j.mimic is not None:
            src = joints.get(j.mimic[0])
            if src is None:
                raise RobotDescriptionError(f"{path}: joint {j.name!r} mimics {j.mimic[0]!r}, which does not exist")
            if not (j.moving and src.moving):
                raise RobotDescriptionError(f"{path}: mimic joint {j.name!r} and its source {src.name!r} must both move")

    parent_of: dict[str, JointInfo] = {}
    for j in joints.values():
        if j.child in parent_of:
            raise RobotDescriptionError(f"{path}: link {j.child!r} has two parent joints ({parent_of[j.child].name!r}, {j.name!r})")
        parent_of[j.child] = j
    roots = [n for n in links if n not in parent_of]
    if len(roots) != 1:
        raise RobotDescriptionError(f"{path}: expected exactly one root link, found {roots}")
    children: dict[str, list[JointInfo]] = {n: [] for n in links}
    for j in joints.values():
        children[j.parent].append(j)
    order_links, order_joints, stack = [], [], [roots[0]]
    while stack:  # depth-first, keeps file order among siblings
        link = stack.pop()
        order_links.append(link)
        for j in reversed(children[link]):
            order_joints.append(j)
            stack.append(j.child)
    if len(order_links) != len(links):
        missing = sorted(set(links) - set(order_links))
        raise RobotDescriptionError(f"{path}: links {missing} are not connected to the root {roots[0]!r} (cycle?)")
    # order_joints is in stack-push order; re-sort so that each joint follows its parent link's joint.
    rank = {n: i for i, n in enumerate(order_links)}
    order_joints.sort(key=lambda j: rank[j.child])
    return URDFModel(robot.name or path.stem, path, roots[0], tuple(order_links), tuple(order_joints), urdf)
