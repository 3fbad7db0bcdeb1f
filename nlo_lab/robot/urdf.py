"""A URDF file as a checked kinematic model: links, joints, limits and mimic rules.

A URDF may come from anywhere, so :func:`load_urdf` reads at most :data:`MAX_URDF_BYTES`
from a regular file, parses the XML without entities, DTDs or external references
(:mod:`~nlo_lab.robot.safe_xml`), refuses a xacro file with the line that expands it, and only
then lets yourdfpy build its objects from the same bytes. :func:`parse_urdf` checks the tree
(one root, every joint naming existing links, no link with two parents, no cycle, known joint
types, finite numbers, every mesh path inside the URDF's folder tree:
:mod:`~nlo_lab.robot.mesh_files`) and orders links and joints parents first. Prismatic,
floating and planar joints and revolute joints without a ``<limit>`` are read; the robot
fixes them (a spec's ``fixed_joints``), and refuses to actuate them. Every problem becomes
one :class:`~nlo_lab.errors.RobotDescriptionError` naming the file.
"""

from __future__ import annotations

import io
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from nlo_lab.errors import RobotDescriptionError, escape
from nlo_lab.files import as_path, read_input_bytes
from nlo_lab.robot.mesh_files import resolve_mesh
from nlo_lab.robot.safe_xml import parse_xml
from nlo_lab.rotations import matrix_to_rpy

__all__ = [
    "MOVING_TYPES",
    "FIXABLE_TYPES",
    "SUPPORTED_TYPES",
    "MAX_URDF_BYTES",
    "XACRO_HINT",
    "JointInfo",
    "URDFModel",
    "load_urdf",
    "parse_urdf",
]

MAX_URDF_BYTES = 16 << 20  # the largest URDF of example-robot-data is well under 1 MB

MOVING_TYPES = ("revolute", "continuous")  # what the robot can actuate
FIXABLE_TYPES = ("prismatic", "floating", "planar")  # read, and fixed by the robot (a spec's fixed_joints)
SUPPORTED_TYPES = MOVING_TYPES + ("fixed",) + FIXABLE_TYPES
XACRO_HINT = "expand it first: pip install xacro; xacro {path} > robot.urdf (xacro needs the ROS packages it names)"


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
        lower: lower limit [rad] (``-pi`` for continuous joints without a limit; [m] for prismatic).
        upper: upper limit [rad].
        mimic: ``(source_joint, multiplier, offset)`` or ``None``.
        has_limit: False for a revolute or prismatic joint without ``<limit>`` (``lower``, ``upper``
            are then -pi, pi: such a joint may be fixed, not actuated).
        velocity: the ``<limit velocity>`` [rad/s], or None when missing or not > 0.
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
    has_limit: bool = True
    velocity: float | None = None

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

    def joint_above(self, link: str) -> JointInfo:
        """The joint whose child is ``link``, which must not be the root."""
        j = self.parent_joint(link)
        if j is None:
            raise RobotDescriptionError(f"{self.path}: {link!r} is the root link: no joint above it")
        return j

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


def _refuse_xacro(path: Path, root) -> None:
    """A xacro file (its suffix, a xacro element, a ``${...}`` or ``$(...)`` to substitute) gets the
    line that expands it. (Expanded URDFs often keep the xacro namespace declaration: that is fine.)"""
    def unexpanded(el) -> bool:
        if isinstance(el.tag, str) and el.tag.startswith("{") and "xacro" in el.tag:
            return True
        return any("${" in v or "$(" in v for v in el.attrib.values())

    if path.suffix.lower() == ".xacro" or any(unexpanded(el) for el in root.iter()):
        raise RobotDescriptionError(f"{path} is a xacro file: {XACRO_HINT.format(path=path)}")


def load_urdf(path: str | Path):
    """Read a URDF file with yourdfpy (no meshes, no scene graph): the one parse of a file.

    The bytes are read once (a regular file of at most :data:`MAX_URDF_BYTES`), parsed without
    entities or DTDs (:func:`~nlo_lab.robot.safe_xml.parse_xml`), and handed to yourdfpy.

    Args:
        path: the ``.urdf`` file.

    Returns:
        The ``yourdfpy.URDF``; :func:`parse_urdf` builds the kinematic model from
        it and the viewer its visuals (``Robot.urdf``).

    Raises:
        RobotDescriptionError: a missing file, malformed XML, entities or a DTD, a xacro file,
            a root element other than ``<robot>``, naming the file.
    """
    import yourdfpy  # imported here: the FK never needs it once the tree is built

    path = as_path(path)
    data = read_input_bytes(path, kind="URDF", max_bytes=MAX_URDF_BYTES, error=RobotDescriptionError)
    root = parse_xml(data, path)
    _refuse_xacro(path, root)
    if root.tag != "robot":
        raise RobotDescriptionError(f"{path}: not a URDF (the root element is <{escape(root.tag)}>, not <robot>)")
    logger = logging.getLogger("yourdfpy")
    recorder = _LogRecorder()
    logger.addHandler(recorder)
    propagate, logger.propagate = logger.propagate, False  # its complaints become our one error
    try:
        urdf = yourdfpy.URDF.load(
            io.BytesIO(data), build_scene_graph=False, build_collision_scene_graph=False, load_meshes=False, load_collision_meshes=False
        )
    except Exception as exc:  # yourdfpy raises assorted types (KeyError, AttributeError, ValueError ...)
        detail = recorder.messages[0] if recorder.messages else f"{type(exc).__name__}: {exc}"
        raise RobotDescriptionError(f"{path}: malformed URDF ({escape(detail)})") from None
    finally:
        logger.removeHandler(recorder)
        logger.propagate = propagate
    if recorder.messages:  # yourdfpy recovers from broken XML; we refuse the file
        raise RobotDescriptionError(f"{path}: malformed URDF XML ({escape(recorder.messages[0])})")
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
            cycle, an unknown joint type, a bad number, a mimic joint whose
            source does not exist, a mesh path leaving the URDF's folder tree.
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
        lower, upper, has_limit, velocity = -math.pi, math.pi, True, None
        if jtype in MOVING_TYPES + ("prismatic",):
            if np.linalg.norm(axis) < 1e-9:
                raise RobotDescriptionError(f"{path}: joint {name!r} has a zero axis")
            axis = axis / np.linalg.norm(axis)
            limit = el.limit
            bounded = jtype != "continuous"
            has_limit = not bounded or limit is not None
            if limit is not None and (limit.lower is not None or bounded):  # URDF: a missing lower or upper is 0
                lower = float(_vector(limit.lower if limit.lower is not None else 0.0, 1, f"joint {name!r} lower limit", path)[0])
                upper = float(_vector(limit.upper if limit.upper is not None else 0.0, 1, f"joint {name!r} upper limit", path)[0])
            if lower > upper:
                raise RobotDescriptionError(f"{path}: joint {name!r} has lower limit {lower} > upper limit {upper}")
            if limit is not None and limit.velocity is not None:
                speed = float(_vector(limit.velocity, 1, f"joint {name!r} velocity limit", path)[0])
                velocity = speed if speed > 0 else None
        mimic = None
        if el.mimic is not None and jtype != "fixed":  # a fixed joint's <mimic> has nothing to follow
            mult = float(_vector(el.mimic.multiplier, 1, f"joint {name!r} mimic multiplier", path)[0])
            off = float(_vector(el.mimic.offset, 1, f"joint {name!r} mimic offset", path)[0])
            mimic = (el.mimic.joint, mult, off)
        joints[name] = JointInfo(name, jtype, el.parent, el.child, origin, axis, lower, upper, mimic, has_limit, velocity)

    for j in joints.values():
        if j.mimic is not None:
            src = joints.get(j.mimic[0])
            if src is None:
                raise RobotDescriptionError(f"{path}: joint {j.name!r} mimics {j.mimic[0]!r}, which does not exist")

    parent_of: dict[str, JointInfo] = {}
    for j in joints.values():
        if j.child in parent_of:
            raise RobotDescriptionError(f"{path}: link {j.child!r} has two parent joints ({parent_of[j.child].name!r}, {j.name!r})")
        parent_of[j.child] = j
    roots = [n for n in links if n not in parent_of]
    if not roots:
        raise RobotDescriptionError(f"{path}: the joints form a cycle: every link has a parent, none is the root")
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
        raise RobotDescriptionError(f"{path}: the joints form a cycle: links {missing} do not hang from the root {roots[0]!r}")
    # order_joints is in stack-push order; re-sort so that each joint follows its parent link's joint.
    rank = {n: i for i, n in enumerate(order_links)}
    order_joints.sort(key=lambda j: rank[j.child])
    for link in robot.links:  # every mesh path must stay in the URDF's folder tree (nothing is read here)
        for element in list(link.visuals or []) + list(link.collisions or []):
            mesh = getattr(element.geometry, "mesh", None) if element.geometry is not None else None
            if mesh is not None and mesh.filename:
                resolve_mesh(str(mesh.filename), path)
    return URDFModel(robot.name or path.stem, path, roots[0], tuple(order_links), tuple(order_joints), urdf)
