"""A robot's spec file: what the URDF does not say.

``load_spec("nao")`` reads ``assets/robots/nao.json``. The spec names the URDF,
fixes the order of the actuated joints, the role links of each arm (shoulder,
elbow, wrist; finger base and tip), the wrist frame's alignment to the human
wrist convention of :mod:`nlo_lab.human.demonstration`, the collision capsules,
the checked pairs and their margins, an optional neutral pose and the published
joint velocity limits (see ``docs/ARCHITECTURE.md`` for the format). Every
problem becomes one :class:`~nlo_lab.errors.RobotDescriptionError` naming the file.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import torch

from nlo_lab.errors import RobotDescriptionError, UnknownRobotError
from nlo_lab.files import as_path, read_input_bytes
from nlo_lab.human.demonstration import FINGERS, SIDES
from nlo_lab.paths import BUNDLED_ROBOTS, ROBOTS_DIR, is_bundled, repair_hint
from nlo_lab.rotations import rpy_to_matrix

__all__ = ["ArmSpec", "CapsuleSpec", "RobotSpec", "load_spec", "known_robots", "spec_text", "MAX_SPEC_BYTES", "FINGER_ALIASES"]

MAX_SPEC_BYTES = 1 << 20  # a robot spec is kB of JSON (the bundled ones 5-45 kB)
FINGER_ALIASES = {"little": "pinky"}  # a spec may name the little finger either way


@dataclass(frozen=True)
class ArmSpec:
    """Role links of one arm.

    Attributes:
        side: ``"left"`` or ``"right"``.
        shoulder, elbow, wrist: link names whose origins are the shoulder,
            elbow and wrist / end-effector points.
        wrist_alignment_rpy: ``(r, p, y)`` [rad] of ``R_wristlink_handframe``: the
            human wrist frame (x along the hand, y little finger -> index,
            z = x cross y) expressed in the wrist link frame.
        fingers: finger name -> ``(base_link, tip_link)`` (empty without hands).
    """

    side: str
    shoulder: str
    elbow: str
    wrist: str
    wrist_alignment_rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)
    fingers: Mapping[str, tuple[str, str]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.side not in SIDES:
            raise RobotDescriptionError(f"arm side must be one of {SIDES}, got {self.side!r}")
        if len(self.wrist_alignment_rpy) != 3 or not all(math.isfinite(v) for v in self.wrist_alignment_rpy):
            raise RobotDescriptionError(f"{self.side} arm: wrist_alignment_rpy must be 3 finite numbers")
        unknown = sorted(set(self.fingers) - set(FINGERS))
        if unknown:
            raise RobotDescriptionError(f"{self.side} arm: unknown fingers {unknown}; expected names from {FINGERS}")

    @property
    def wrist_alignment(self) -> torch.Tensor:
        """``(3, 3)`` float64 ``R_wristlink_handframe``."""
        return torch.as_tensor(rpy_to_matrix(self.wrist_alignment_rpy))

    @property
    def links(self) -> tuple[str, ...]:
        """Every link the arm names (roles and finger frames)."""
        return (self.shoulder, self.elbow, self.wrist) + tuple(x for pair in self.fingers.values() for x in pair)


@dataclass(frozen=True)
class CapsuleSpec:
    """A collision capsule: a segment in a link frame swept by a sphere.

    Attributes:
        name: unique name (``"l_forearm"``).
        link: the link it is attached to.
        p0, p1: segment end points in the link frame [m].
        radius: [m], > 0.
    """

    name: str
    link: str
    p0: tuple[float, float, float]
    p1: tuple[float, float, float]
    radius: float

    def __post_init__(self) -> None:
        if not (isinstance(self.radius, (int, float)) and self.radius > 0 and math.isfinite(self.radius)):
            raise RobotDescriptionError(f"capsule {self.name!r}: radius must be > 0, got {self.radius!r}")
        for key in ("p0", "p1"):
            v = getattr(self, key)
            if len(v) != 3 or not all(math.isfinite(x) for x in v):
                raise RobotDescriptionError(f"capsule {self.name!r}: {key} must be 3 finite numbers, got {v!r}")


@dataclass(frozen=True)
class RobotSpec:
    """The contents of a robot spec file.

    Attributes:
        name: robot name.
        path: the spec file.
        urdf: the URDF file (resolved).
        base_link: the link the arms hang from and the robot frame sits on: the URDF's root
            for the bundled robots (their root is already the robot frame), any link above both
            shoulders with no actuated joint above it for a drafted spec.
        actuated_joints: order of :attr:`Robot.joint_names`.
        arms: ``{"left": ArmSpec, "right": ArmSpec}``.
        capsules: the collision capsules.
        collision_pairs: pairs of capsule names that are checked.
        pair_margins: d_min [m] of each pair, same order.
        description: free text.
        neutral_pose: optional ``((joint, angle [rad]), ...)``: a collision-free
            rest pose (YuMi's all-zero pose crosses the forearms).
        velocity_limits: optional ``((joint, max speed [rad/s]), ...)``, the published
            joint velocity limits (spec ``"velocity_limits"``; source in ``"velocity_limits_source"``).
        velocity_limits_source: where the velocity limits come from (free text).
        fixed_joints: optional ``((joint, value), ...)``: the URDF's moving joints the robot does not
            actuate, fixed at these values [rad or m] (their mimic joints follow). Without this field
            every moving joint must be actuated or mimic one (the bundled robots).
        robot_frame: optional ``(xyz, rpy)``: the robot frame (origin between the shoulders, X forward,
            Y left, Z up) in ``base_link``'s frame at the fixed joints' values; without it, base_link's frame.
        srdf: optional SRDF file (spec ``"srdf"``, relative to the spec): its disabled collision pairs are
            left out of the self-collision check by the URDF's geometry (:mod:`nlo_lab.robot.srdf`).
        shape_contacts: optional link pairs (spec ``"shape_contacts"``) whose collision elements meet where their
            visual parts do not (found by ``nlo-lab robot init``): left out of that check too.
    """

    name: str
    path: Path
    urdf: Path
    base_link: str
    actuated_joints: tuple[str, ...]
    arms: Mapping[str, ArmSpec]
    capsules: tuple[CapsuleSpec, ...]
    collision_pairs: tuple[tuple[str, str], ...]
    pair_margins: tuple[float, ...]
    description: str = ""
    neutral_pose: tuple[tuple[str, float], ...] | None = None
    velocity_limits: tuple[tuple[str, float], ...] | None = None
    velocity_limits_source: str = ""
    fixed_joints: tuple[tuple[str, float], ...] | None = None
    robot_frame: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    srdf: Path | None = None
    shape_contacts: tuple[tuple[str, str], ...] = ()

    def __post_init__(self) -> None:
        if set(self.arms) != set(SIDES):
            raise RobotDescriptionError(f"{self.path}: 'arms' must have exactly {SIDES}, got {sorted(self.arms)}")
        if len(self.pair_margins) != len(self.collision_pairs):
            raise RobotDescriptionError(f"{self.path}: one margin per collision pair expected")
        if any(not (m >= 0 and math.isfinite(m)) for m in self.pair_margins):
            raise RobotDescriptionError(f"{self.path}: collision margins must be finite and >= 0")

    def capsule(self, name: str) -> CapsuleSpec:
        for c in self.capsules:
            if c.name == name:
                return c
        raise KeyError(name)


def spec_text(data: dict) -> str:
    """A spec as JSON text: indented, with each short list or flat object (a point, a pair, a capsule) on one line."""

    def one_line(value) -> str | None:
        text = json.dumps(value, ensure_ascii=False, separators=(", ", ": "))
        flat = not isinstance(value, (dict, list)) or all(
            not isinstance(v, (dict, list)) or (isinstance(v, list) and all(not isinstance(x, (dict, list)) for x in v))
            for v in (value.values() if isinstance(value, dict) else value)
        )
        return text if flat and len(text) <= 150 else None

    def render(value, indent: int) -> str:
        short = one_line(value)
        if short is not None or not isinstance(value, (dict, list)):  # a long string stays one string
            return short or json.dumps(value, ensure_ascii=False)
        pad, inner = " " * indent, " " * (indent + 2)
        if isinstance(value, dict):
            items = [f"{inner}{json.dumps(k, ensure_ascii=False)}: {render(v, indent + 2)}" for k, v in value.items()]
            return "{\n" + ",\n".join(items) + f"\n{pad}}}"
        return "[\n" + ",\n".join(f"{inner}{render(v, indent + 2)}" for v in value) + f"\n{pad}]"

    return render(data, 0) + "\n"


def known_robots() -> list[str]:
    """Names of the bundled robots (spec files in ``assets/robots``)."""
    return sorted(p.stem for p in ROBOTS_DIR.glob("*.json"))


def _resolve(name_or_path: str | Path) -> Path:
    p = as_path(name_or_path, "robot")
    # A bundled name wins over a same-named file or folder in the working directory.
    if isinstance(name_or_path, str) and name_or_path in known_robots():
        return ROBOTS_DIR / f"{name_or_path}.json"
    if p.suffix == ".json" or os.path.lexists(p) or len(p.parts) > 1:
        return p  # load_spec checks the file before it opens it
    spec = ROBOTS_DIR / f"{name_or_path}.json"
    if not spec.is_file() and name_or_path in BUNDLED_ROBOTS:
        raise RobotDescriptionError(f"robot spec file not found: {spec}; {repair_hint(spec)}")
    if not spec.is_file():
        raise UnknownRobotError(f"unknown robot {str(name_or_path)!r}; known robots: {', '.join(known_robots())} (or give a path to a spec .json)")
    return spec


def _need(d: dict, key: str, where: str, path: Path):
    if not isinstance(d, dict) or key not in d:
        raise RobotDescriptionError(f"{path}: {where} is missing the field {key!r}")
    return d[key]


def _vec3(v, what: str, path: Path) -> tuple[float, float, float]:
    try:
        out = tuple(float(x) for x in v)
    except (TypeError, ValueError):
        raise RobotDescriptionError(f"{path}: {what} must be 3 numbers, got {v!r}") from None
    if len(out) != 3:
        raise RobotDescriptionError(f"{path}: {what} must be 3 numbers, got {v!r}")
    return out


def load_spec(name_or_path: str | Path) -> RobotSpec:
    """Read a robot spec file (no URDF checks; :func:`load_robot` does those).

    Args:
        name_or_path: a bundled robot name or a path to a spec ``.json``.

    Raises:
        UnknownRobotError: a name that is not bundled.
        RobotDescriptionError: a missing or malformed file or field.
    """
    path = _resolve(name_or_path)
    raw = read_input_bytes(path, kind="robot spec", max_bytes=MAX_SPEC_BYTES, error=RobotDescriptionError)
    try:
        data = json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        hint = f"; {repair_hint(path)}" if is_bundled(path) else ""
        raise RobotDescriptionError(f"{path}: not a text file (a robot spec is UTF-8 JSON){hint}") from None
    except (json.JSONDecodeError, RecursionError) as e:
        hint = f"; {repair_hint(path)}" if is_bundled(path) else ""
        raise RobotDescriptionError(f"{path}: malformed JSON ({e}){hint}") from None
    if not isinstance(data, dict):
        raise RobotDescriptionError(f"{path}: the spec must be a JSON object")
    urdf = Path(os.path.normpath(path.parent / str(_need(data, "urdf", "the spec", path))))
    actuated = _need(data, "actuated_joints", "the spec", path)
    if not isinstance(actuated, list) or not all(isinstance(a, str) for a in actuated) or not actuated:
        raise RobotDescriptionError(f"{path}: 'actuated_joints' must be a non-empty list of joint names")
    arms = {}
    arms_data = _need(data, "arms", "the spec", path)
    for side in SIDES:
        a = _need(arms_data, side, "'arms'", path)
        fingers = {}
        for fname, pair in (a.get("fingers") or {}).items():
            if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(x, str) for x in pair)):
                raise RobotDescriptionError(f"{path}: arms.{side}.fingers.{fname} must be [base_link, tip_link]")
            fname = FINGER_ALIASES.get(fname, fname)
            if fname in fingers:
                raise RobotDescriptionError(f"{path}: arms.{side}.fingers names the {fname} finger twice (little and pinky are one)")
            fingers[fname] = (pair[0], pair[1])
        try:
            arms[side] = ArmSpec(
                side,
                str(_need(a, "shoulder", f"arms.{side}", path)),
                str(_need(a, "elbow", f"arms.{side}", path)),
                str(_need(a, "wrist", f"arms.{side}", path)),
                _vec3(a.get("wrist_alignment_rpy", [0, 0, 0]), f"arms.{side}.wrist_alignment_rpy", path),
                fingers,
            )
        except RobotDescriptionError as e:
            raise RobotDescriptionError(f"{path}: {e}") from None
    capsules = []
    for i, c in enumerate(data.get("capsules", [])):
        where = f"capsules[{i}]"
        try:
            capsules.append(
                CapsuleSpec(
                    str(_need(c, "name", where, path)),
                    str(_need(c, "link", where, path)),
                    _vec3(_need(c, "p0", where, path), f"{where}.p0", path),
                    _vec3(_need(c, "p1", where, path), f"{where}.p1", path),
                    float(_need(c, "radius", where, path)),
                )
            )
        except (TypeError, ValueError):
            raise RobotDescriptionError(f"{path}: {where}.radius must be a number") from None
        except RobotDescriptionError as e:
            raise RobotDescriptionError(f"{path}: {e}" if str(path) not in str(e) else str(e)) from None
    names = [c.name for c in capsules]
    if len(set(names)) != len(names):
        raise RobotDescriptionError(f"{path}: duplicate capsule names {sorted({n for n in names if names.count(n) > 1})}")
    pairs = []
    for i, pr in enumerate(data.get("collision_pairs", [])):
        if not (isinstance(pr, list) and len(pr) == 2):
            raise RobotDescriptionError(f"{path}: collision_pairs[{i}] must be [capsule_a, capsule_b]")
        for n in pr:
            if n not in names:
                raise RobotDescriptionError(f"{path}: collision_pairs[{i}] names capsule {n!r}, which does not exist")
        if pr[0] == pr[1]:
            raise RobotDescriptionError(f"{path}: collision_pairs[{i}] pairs capsule {pr[0]!r} with itself")
        pairs.append((pr[0], pr[1]))
    margin_data = data.get("collision_margin", {"default": 0.1})
    if isinstance(margin_data, (int, float)) and not isinstance(margin_data, bool):
        margin_data = {"default": margin_data}
    if not isinstance(margin_data, dict) or not all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in margin_data.values()
    ):
        raise RobotDescriptionError(f"{path}: collision_margin must be a number or map 'default' and 'a/b' pairs to numbers [m]")
    default = float(margin_data.get("default", 0.1))
    overrides = {}
    for key, value in margin_data.items():
        if key == "default":
            continue
        a, _, b = key.partition("/")
        if (a, b) not in pairs and (b, a) not in pairs:
            raise RobotDescriptionError(f"{path}: collision_margin names the pair {key!r}, which is not in collision_pairs")
        overrides[frozenset((a, b))] = float(value)
    margins = tuple(overrides.get(frozenset(p), default) for p in pairs)
    neutral = data.get("neutral_pose")
    if neutral is not None:
        if not isinstance(neutral, dict) or not all(isinstance(v, (int, float)) for v in neutral.values()):
            raise RobotDescriptionError(f"{path}: 'neutral_pose' must map joint names to angles [rad]")
        unknown = sorted(set(neutral) - set(actuated))
        if unknown:
            raise RobotDescriptionError(f"{path}: neutral_pose names joints {unknown} that are not in actuated_joints")
        neutral = tuple((str(k), float(v)) for k, v in neutral.items())
    velocity = data.get("velocity_limits")
    if velocity is not None:
        if not isinstance(velocity, dict) or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and v > 0 and math.isfinite(v) for v in velocity.values()
        ):
            raise RobotDescriptionError(f"{path}: 'velocity_limits' must map joint names to speeds > 0 [rad/s]")
        velocity = tuple((str(k), float(v)) for k, v in velocity.items())
    fixed = data.get("fixed_joints")
    if fixed is not None:
        if not isinstance(fixed, dict) or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                                                  for v in fixed.values()):
            raise RobotDescriptionError(f"{path}: 'fixed_joints' must map joint names to values [rad or m]")
        both = sorted(set(fixed) & set(actuated))
        if both:
            raise RobotDescriptionError(f"{path}: joints {both} are both actuated and fixed")
        fixed = tuple((str(k), float(v)) for k, v in fixed.items())
    frame = data.get("robot_frame")
    if frame is not None:
        if not isinstance(frame, dict):
            raise RobotDescriptionError(f"{path}: 'robot_frame' must be {{\"xyz\": [x, y, z], \"rpy\": [r, p, y]}}")
        frame = (_vec3(frame.get("xyz", [0, 0, 0]), "robot_frame.xyz", path), _vec3(frame.get("rpy", [0, 0, 0]), "robot_frame.rpy", path))
        if not all(math.isfinite(v) for part in frame for v in part):
            raise RobotDescriptionError(f"{path}: robot_frame must hold finite numbers")
    contacts = data.get("shape_contacts", [])
    if not isinstance(contacts, list) or not all(isinstance(p, list) and len(p) == 2 and all(isinstance(n, str) for n in p) for p in contacts):
        raise RobotDescriptionError(f"{path}: 'shape_contacts' must be a list of [link, link] pairs")
    return RobotSpec(
        name=str(data.get("name", path.stem)),
        path=path,
        urdf=urdf,
        base_link=str(data.get("base_link", "world")),
        actuated_joints=tuple(actuated),
        arms=arms,
        capsules=tuple(capsules),
        collision_pairs=tuple(pairs),
        pair_margins=margins,
        description=str(data.get("description", "")),
        neutral_pose=neutral,
        velocity_limits=velocity,
        velocity_limits_source=str(data.get("velocity_limits_source", "")),
        fixed_joints=fixed,
        robot_frame=frame,
        srdf=None if data.get("srdf") is None else path.parent / str(data["srdf"]),
        shape_contacts=tuple((a, b) for a, b in contacts),
    )
