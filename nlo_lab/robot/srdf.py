"""The pairs of links a robot's SRDF says never to check for collision.

Real robot descriptions come with an SRDF (MoveIt's semantic description) whose
``<disable_collisions link1 link2 reason>`` entries name the link pairs their makers do not
check: adjacent links, links in contact at the default pose, pairs that can never meet, and
pairs their coarse collision shapes make collide where the robot does not ("User": Baxter's
shoulder column and upper arm). A spec may name that file (``"srdf"``): the self-collision
check by the URDF's geometry and ``nlo-lab robot init --srdf`` then leave those pairs out,
as the robot's makers do. The file is read like a URDF: bounded, without entities or DTDs.
"""

from __future__ import annotations

from pathlib import Path

from nlo_lab.errors import RobotDescriptionError
from nlo_lab.files import read_input_bytes
from nlo_lab.robot.safe_xml import parse_xml

__all__ = ["MAX_SRDF_BYTES", "disabled_pairs"]

MAX_SRDF_BYTES = 16 << 20  # PR2's SRDF, with 1163 disabled pairs, is 150 kB


def disabled_pairs(path: str | Path) -> set[frozenset[str]]:
    """The link pairs of every ``<disable_collisions>`` entry of the SRDF at ``path``.

    Raises:
        RobotDescriptionError: a missing, oversized or malformed file, or one that declares entities.
    """
    path = Path(path)
    root = parse_xml(read_input_bytes(path, kind="SRDF", max_bytes=MAX_SRDF_BYTES, error=RobotDescriptionError), path)
    if root.tag != "robot":
        raise RobotDescriptionError(f"{path}: not an SRDF (the root element is <{root.tag}>, not <robot>)")
    out = set()
    for el in root.iter("disable_collisions"):
        a, b = el.get("link1"), el.get("link2")
        if not a or not b:
            raise RobotDescriptionError(f"{path}: a <disable_collisions> lacks link1 or link2 (line {el.sourceline})")
        out.add(frozenset((a, b)))
    return out
