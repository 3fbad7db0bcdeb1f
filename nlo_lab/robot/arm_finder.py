"""Finding a robot's two arms (and fingers) in a URDF tree, from its structure and its names.

An **arm** is a serial chain of moving joints that starts on the body and ends where the
hand branches into fingers (or where the chain ends). :func:`find_arms` tags each link's
side from its name (``left``/``right``, ``l_``/``r_``, ``_l``/``_r``, NAO's ``LShoulder``),
leaves out legs, heads, wheels and grippers by name, and takes for each side the chain with
the most joints; without side names it takes two chains hanging from one link, the left one
being the one at larger Y (the URDF convention: X forward, Y left, Z up).

On the chain, the roles (what :func:`arm_roles` returns, the six links ``nlo-lab robot init``
prints):

* **wrist**: the child of the last moving joint before the hand branches, a gripper or finger
  joint begins, or the chain ends;
* **shoulder**: the child of the first joint, unless the second joint sits elsewhere (more
  than :data:`SAME_POINT` away): then the first is a turret on the body (YuMi's, Baxter's,
  TIAGo's, Talos' and PR2's joint 1) and the shoulder is the second joint's child;
* **elbow**: among the joints between them whose axis crosses the arm (a flexion, not a roll),
  the one farthest from both (the first link at that point when several joints share it).

A finger is a chain below the wrist whose links name it (``thumb``, ``index``, ``middle``,
``ring``, ``little``/``pinky``): its tip is the deepest link of the longest such chain, its
base the child of the chain's first moving joint below the wrist (:func:`find_fingers`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from nlo_lab.errors import RobotDescriptionError
from nlo_lab.robot.fixed_joints import joint_motion
from nlo_lab.robot.urdf import URDFModel

__all__ = ["SAME_POINT", "ArmChain", "side_of", "rest_poses", "find_arms", "arm_chain", "arm_roles", "find_fingers"]

SAME_POINT = 0.01  # [m] joint origins closer than this are one point (a shoulder of 2-3 joints)
_NOT_ARM = re.compile(r"leg|hip|knee|ankle|foot|feet|sole|toe|thigh|shin|calf|wheel|caster|head|neck|eye|ear|camera|sensor|laser|torso")
_HAND = re.compile(r"gripper|finger|thumb|palm")  # an arm's chain stops where these begin
_FINGER_NAMES = {"thumb": ("thumb",), "index": ("index",), "middle": ("middle",), "ring": ("ring",), "pinky": ("little", "pinky")}


@dataclass(frozen=True)
class ArmChain:
    """One arm as found: its moving joints from the body to the wrist, and the roles.

    Attributes:
        side: ``"left"`` or ``"right"``.
        joints: the moving joints from the body down to the wrist, in order.
        shoulder, elbow, wrist: the role links.
    """

    side: str
    joints: tuple[str, ...]
    shoulder: str
    elbow: str
    wrist: str


def side_of(name: str) -> str | None:
    """``"left"``, ``"right"`` or None, from a link or joint name."""
    low = name.lower()
    for side, word, letter in (("left", "left", "l"), ("right", "right", "r")):
        if word in low or re.search(rf"(^|[^a-z]){letter}([^a-z]|$)", low) or re.match(rf"^{letter.upper()}[A-Z]", name):
            return side
    return None


def rest_poses(model: URDFModel) -> dict[str, np.ndarray]:
    """``{link: T_root_link}`` with every joint at zero clamped into its limits."""
    T = {model.root: np.eye(4)}
    for j in model.joints:
        value = 0.0 if j.type == "fixed" else float(np.clip(0.0, j.lower, j.upper))
        T[j.child] = T[j.parent] @ j.origin @ joint_motion(j, value)
    return T


def _children(model: URDFModel) -> dict[str, list]:
    out: dict[str, list] = {n: [] for n in model.links}
    for j in model.joints:
        out[j.parent].append(j)
    return out


def _moving_below(model: URDFModel, children: dict) -> dict[str, int]:
    """Link -> the number of moving joints in its subtree."""
    count: dict[str, int] = {}
    for link in reversed(model.links):
        count[link] = sum((j.type != "fixed") + count[j.child] for j in children[link])
    return count


def arm_chain(model: URDFModel, start: str) -> tuple[list[str], str]:
    """The moving joints from link ``start`` down to where the chain branches (a hand) or ends, and
    the wrist link (the last moving joint's child)."""
    children = _children(model)
    below = _moving_below(model, children)
    joints: list[str] = []
    link, wrist = start, start
    while True:
        ways = [j for j in children[link] if j.type != "fixed" or below[j.child] > 0]
        if len(ways) != 1 or (ways[0].type != "fixed" and _HAND.search(ways[0].child.lower())):
            return joints, wrist
        j = ways[0]
        if j.type != "fixed":
            joints.append(j.name)
            wrist = j.child
        link = j.child


def _starts(model: URDFModel) -> list:
    """Moving joints where a side-named chain leaves the body: the first moving joint on the way down
    to a link of that side (not legs, heads, wheels)."""
    out = []
    for j in model.joints:
        side = side_of(j.child)
        if j.type == "fixed" or not side or _NOT_ARM.search(j.child.lower()) or _NOT_ARM.search(j.name.lower()):
            continue
        up, first = model.parent_joint(j.parent), True
        while up is not None:
            if up.type != "fixed" and side_of(up.child) == side:
                first = False
                break
            up = model.parent_joint(up.parent)
        if first:
            out.append(j)
    return out


def arm_roles(model: URDFModel, side: str, joints: list[str], wrist: str, poses=None) -> ArmChain:
    """The shoulder, elbow and wrist links of an arm chain (see the module docstring)."""
    if len(joints) < 2:
        raise RobotDescriptionError(f"{model.path}: the {side} arm has {len(joints)} moving joint(s); an arm needs at least 2")
    poses = poses or rest_poses(model)
    by_name = {j.name: j for j in model.joints}
    links = [by_name[n].child for n in joints]
    p = [poses[link][:3, 3] for link in links]
    shoulder = 0 if np.linalg.norm(p[1] - p[0]) <= SAME_POINT else 1
    ps, pw = p[shoulder], poses[wrist][:3, 3]

    def unit(v):
        n = np.linalg.norm(v)
        return v / n if n > SAME_POINT else np.zeros(3)

    def bends(k: int) -> bool:
        """The joint's axis crosses the arm (a flexion), not along it (a roll)."""
        axis = poses[links[k]][:3, :3] @ by_name[joints[k]].axis
        return abs(axis @ unit(pw - p[k])) < 0.7 and abs(axis @ unit(p[k] - ps)) < 0.7

    candidates = [k for k in range(shoulder + 1, len(links)) if bends(k)] or list(range(shoulder + 1, len(links)))
    best, elbow = -1.0, candidates[0] if candidates else len(links) - 1
    for k in candidates:
        score = float(min(np.linalg.norm(p[k] - ps), np.linalg.norm(pw - p[k])))
        if score > best + SAME_POINT:
            best, elbow = score, k
    while elbow > shoulder + 1 and np.linalg.norm(p[elbow - 1] - p[elbow]) <= SAME_POINT:
        elbow -= 1  # the first link at the elbow's point (NAO: LElbow, where ElbowYaw and ElbowRoll meet)
    return ArmChain(side, tuple(joints), links[shoulder], links[elbow], wrist)


def find_arms(model: URDFModel) -> dict[str, ArmChain]:
    """The two arms of ``model`` (see the module docstring).

    Raises:
        RobotDescriptionError: fewer than two arm chains found, naming the file and what to pass.
    """
    poses = rest_poses(model)
    by_side: dict[str, list] = {"left": [], "right": []}
    for j in _starts(model):
        joints, wrist = arm_chain(model, j.child)
        side = side_of(j.child)
        if len(joints) >= 2 and side is not None:  # _starts gives sided links only
            by_side[side].append((len(joints) + 1, [j.name, *joints], wrist))
    if not (by_side["left"] and by_side["right"]):
        by_side = _unnamed_pair(model, poses)
    if not (by_side["left"] and by_side["right"]):
        raise RobotDescriptionError(
            f"{model.path}: no two arms found (chains of 3 or more moving joints on the left and right); "
            "name them with --left-arm SHOULDER,ELBOW,WRIST and --right-arm SHOULDER,ELBOW,WRIST")
    out = {}
    for side in ("left", "right"):
        _, joints, wrist = max(by_side[side], key=lambda item: item[0])
        out[side] = arm_roles(model, side, joints, wrist, poses)
    return out


def _unnamed_pair(model: URDFModel, poses) -> dict[str, list]:
    """Two chains of 3+ joints hanging from one link, without side names: left = larger Y."""
    children = _children(model)
    best = None
    for link in model.links:
        chains = []
        for j in children[link]:
            if j.type == "fixed" or _NOT_ARM.search(j.child.lower()):
                continue
            joints, wrist = arm_chain(model, j.child)
            joints = [j.name, *joints]
            if len(joints) >= 3:
                chains.append((len(joints), joints, wrist, j.child))
        if len(chains) >= 2:
            pair = sorted(chains, key=lambda c: -c[0])[:2]
            if best is None or pair[1][0] > best[1][0]:
                best = pair
    if best is None:
        return {"left": [], "right": []}
    a, b = sorted(best, key=lambda c: -poses[c[3]][1, 3])  # by where the chains start: arms may cross at rest
    return {"left": [a[:3]], "right": [b[:3]]}


def find_fingers(model: URDFModel, wrist: str) -> dict[str, tuple[str, str]]:
    """Finger -> ``(base, tip)`` links below ``wrist``, found by name (see the module docstring)."""
    children = _children(model)
    out = {}
    for finger, words in _FINGER_NAMES.items():
        best = None
        for tip in model.subtree(wrist):
            if children[tip] or not any(w in tip.lower() for w in words):
                continue  # tips are leaves
            path, link = [], tip
            while link != wrist:
                j = model.joint_above(link)
                path.append(j)
                link = j.parent
            moving = [j for j in reversed(path) if j.type != "fixed"]
            if moving and (best is None or len(moving) > best[0]):
                best = (len(moving), moving[0].child, tip)
        if best is not None:
            out[finger] = (best[1], best[2])
    return out
