"""Generate ``yumi.urdf`` and ``yumi.json``: ABB YuMi (IRB 14000) with two Inspire RH56 hands.

Regenerate (from the repository root)::

    .venv/bin/python assets/robots/make_yumi_urdf.py

The numbers (joint origins, limits, coupling ratios, finger offsets) are facts
taken from the public descriptions cited in ``YUMI.md`` (ABB YuMi description of
Örebro University ``yumi_description``, BSD-2; Inspire RH56 figures from
dexsuite ``dex-urdf`` and the MuJoCo Menagerie model, BSD-3). The files, the
geometry (primitives only) and every derived number are ours, written here.

Derived numbers (computed below at the zero pose, all joints 0):

* the offset of the top fixed joint ``world -> yumi_base_link`` that puts the
  midpoint of the two shoulder frames (``yumi_link_2_l/r``) at the origin;
* the fixed rotation ``wrist_alignment_rpy`` per side, from the wrist link
  ``yumi_link_7_x`` to the human wrist-frame convention (x from the wrist
  towards the middle-finger base, y from the little finger towards the index);
* a collision-free ``neutral_pose`` (YuMi's all-zero pose brings both flanges
  to the same point in front of the body, see ``YUMI.md``).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fit_capsules  # noqa: E402  (the collision capsules, fitted to the URDF written here)

HERE = Path(__file__).resolve().parent
URDF_PATH = HERE / "yumi.urdf"
SPEC_PATH = HERE / "yumi.json"

PI = math.pi
SIDES = ("l", "r")
SIDE_NAMES = {"l": "left", "r": "right"}

# --------------------------------------------------------------------------- facts
# Arm chain, left side (yumi_description). Order along the chain: 1, 2, 7, 3, 4, 5, 6.
# (joint number, origin xyz [m], origin rpy [rad], lower, upper [rad], max velocity [rad/s], effort [N m])
ARM_CHAIN = (
    (1, (0.05355, 0.07250, 0.41492), (0.9781, -0.5716, 2.3180), -2.94088, 2.94088, 3.1416, 36.0),
    (2, (0.03, 0.0, 0.1), (1.5708, 0.0, 0.0), -2.50455, 0.75922, 3.1416, 36.0),
    (7, (-0.03, 0.17283, 0.0), (-1.5708, 0.0, 0.0), -2.94088, 2.94088, 3.1416, 24.0),
    (3, (-0.04188, 0.0, 0.07873), (1.5708, -1.5708, 0.0), -2.15548, 1.39626, 3.1416, 24.0),
    (4, (0.0405, 0.16461, 0.0), (-1.5708, 0.0, 0.0), -5.06145, 5.06145, 6.9813, 12.0),
    (5, (-0.027, 0.0, 0.10039), (1.5708, 0.0, 0.0), -1.53589, 2.40855, 6.9813, 12.0),
    (6, (0.027, 0.029, 0.0), (-1.5708, 0.0, 0.0), -3.99680, 3.99680, 6.9813, 12.0),
)
# Right arm: identical except joint 1's origin.
JOINT1_RIGHT = ((0.05355, -0.0725, 0.41492), (-0.9795, -0.5682, -2.3155))
# Tool flange: link_7 -> hand/gripper base.
FLANGE_XYZ, FLANGE_RPY = (0.0, 0.0, 0.007), (0.0, 0.0, PI)

# Inspire RH56, right hand, in its base frame: fingers along -y, index at -z,
# pinky at +z, back of the hand +x (the palm and the thumb are on the -x side).
HAND_VELOCITY = 2.0  # [rad/s] assumed: no published figure (see HAND_VELOCITY_ASSUMED, the spec's velocity_limits)
HAND_EFFORT = 1.0  # [N m]
# finger: (knuckle xyz, knuckle roll, proximal->intermediate xyz, intermediate->tip xyz)
FINGERS = {
    "index": ((0.00028533, -0.13653, -0.032268), -3.1067, (-0.0026138, 0.032026, -0.001), (-0.0008, 0.045, -0.005)),
    "middle": ((0.00028533, -0.1371, -0.01295), -3.1416, (-0.0024229, 0.032041, -0.001), (-0.001, 0.048, -0.005)),
    "ring": ((0.00028533, -0.13691, 0.0062872), 3.0892, (-0.0024229, 0.032041, -0.001), (-0.0008, 0.045, -0.005)),
    "pinky": ((0.00028533, -0.13571, 0.025488), 3.0369, (-0.0024229, 0.032041, -0.001), (-0.0008, 0.037, -0.005)),
}
FINGER_PROXIMAL_LIMITS = (0.0, 1.47)
FINGER_MIMIC = (1.06399, -0.04545)  # intermediate = 1.06399 * proximal - 0.04545
THUMB_YAW = ((-0.01696, -0.0691, -0.02045), (1.5708, -1.5708, 0.0), (0.0, 1.308))
THUMB_PITCH = ((-0.0088099, 0.010892, -0.00925), (1.5708, 0.0, 2.8587), (0.0, 0.6))
THUMB_INTERMEDIATE_XYZ = (0.04407, 0.034553, -0.0008)  # 56.0 mm
THUMB_DISTAL_XYZ = (0.020248, 0.010156, -0.0012)  # 22.7 mm
THUMB_TIP_XYZ = (0.0202, 0.0140, -0.006)  # 25.3 mm
THUMB_INTERMEDIATE_MIMIC = (1.334, 0.0)
THUMB_DISTAL_MIMIC = (0.667, 0.0)

# The hand's fingers run along -y of its base frame (+y on the mirrored left
# hand); a fixed mount joint turns them onto +z of the flange, so that the hand
# continues the forearm. The palm faces +x of yumi_link_7 on both sides.
HAND_MOUNT_RPY = {"r": (-PI / 2, 0.0, 0.0), "l": (PI / 2, 0.0, 0.0)}

# Geometry radii [m]
R_ARM = 0.045  # link tubes
R_JOINT = 0.05  # joint housings
R_FINGER = 0.008

MATERIALS = {
    "yumi_grey": (0.82, 0.82, 0.84, 1.0),
    "yumi_dark": (0.32, 0.33, 0.36, 1.0),
    "yumi_body": (0.70, 0.71, 0.74, 1.0),
    "hand_blue": (0.22, 0.42, 0.72, 1.0),
    "finger_black": (0.12, 0.12, 0.14, 1.0),
}


# --------------------------------------------------------------------------- maths
def rot_rpy(rpy) -> np.ndarray:
    """URDF rpy (fixed axes x, y, z) -> 3x3 rotation ``Rz(y) Ry(p) Rx(r)``."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def rpy_of(rot: np.ndarray) -> tuple[float, float, float]:
    """3x3 rotation -> URDF rpy (inverse of :func:`rot_rpy`, away from pitch = +-pi/2)."""
    p = math.asin(max(-1.0, min(1.0, -rot[2, 0])))
    r = math.atan2(rot[2, 1], rot[2, 2])
    y = math.atan2(rot[1, 0], rot[0, 0])
    return (r, p, y)


def transform(xyz, rpy) -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = rot_rpy(rpy)
    t[:3, 3] = xyz
    return t


def mirror_xyz(xyz):
    """Reflection through the x-z plane of the hand base frame (right hand -> left hand)."""
    return (xyz[0], -xyz[1], xyz[2])


def mirror_rpy(rpy):
    """``M R M`` with ``M = diag(1, -1, 1)`` in rpy form."""
    return (-rpy[0], rpy[1], -rpy[2])


def mirror_axis(axis):
    """A mirrored revolute joint keeps its sense of motion with axis ``-M a``."""
    return (-axis[0], axis[1], -axis[2])


def align_z_rpy(vec) -> tuple[float, float, float]:
    """rpy of a frame whose z axis points along ``vec`` (for cylinders)."""
    v = np.asarray(vec, dtype=float)
    v = v / np.linalg.norm(v)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, v)
    s, c = np.linalg.norm(axis), float(z @ v)
    if s < 1e-12:
        return (0.0, 0.0, 0.0) if c > 0 else (PI, 0.0, 0.0)
    k = axis / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    rot = np.eye(3) + s * kx + (1 - c) * kx @ kx
    return rpy_of(rot)


def fmt(values) -> str:
    out = []
    for v in values:
        v = 0.0 if abs(v) < 5e-13 else float(v)
        out.append(f"{v:.10g}")
    return " ".join(out)


# --------------------------------------------------------------------------- URDF text
class Urdf:
    """Collects links and joints as text; also records the fixed structure for our own FK."""

    def __init__(self) -> None:
        self.parts: list[str] = []
        self.joints: dict[str, dict] = {}  # child link -> joint record

    def link(self, name: str, shapes: list[tuple] = ()) -> None:
        """shapes: (kind, size, xyz, rpy, material, collide)."""
        body = []
        for kind, size, xyz, rpy, material, collide in shapes:
            if kind == "cylinder":
                geom = f'<cylinder radius="{size[0]:.6g}" length="{size[1]:.6g}"/>'
            elif kind == "box":
                geom = f'<box size="{fmt(size)}"/>'
            else:
                geom = f'<sphere radius="{size[0]:.6g}"/>'
            origin = f'<origin xyz="{fmt(xyz)}" rpy="{fmt(rpy)}"/>'
            body.append(
                f"    <visual>\n      {origin}\n      <geometry>{geom}</geometry>\n"
                f'      <material name="{material}"/>\n    </visual>'
            )
            if collide:
                body.append(f"    <collision>\n      {origin}\n      <geometry>{geom}</geometry>\n    </collision>")
        if body:
            self.parts.append(f'  <link name="{name}">\n' + "\n".join(body) + "\n  </link>")
        else:
            self.parts.append(f'  <link name="{name}"/>')

    def joint(self, name, kind, parent, child, xyz, rpy, axis=None, limits=None, mimic=None) -> None:
        lines = [
            f'  <joint name="{name}" type="{kind}">',
            f'    <parent link="{parent}"/>',
            f'    <child link="{child}"/>',
            f'    <origin xyz="{fmt(xyz)}" rpy="{fmt(rpy)}"/>',
        ]
        if axis is not None:
            lines.append(f'    <axis xyz="{fmt(axis)}"/>')
        if limits is not None:
            lo, hi, vel, eff = limits
            lines.append(f'    <limit lower="{lo:.10g}" upper="{hi:.10g}" velocity="{vel:.10g}" effort="{eff:.10g}"/>')
        if mimic is not None:
            src, mult, off = mimic
            lines.append(f'    <mimic joint="{src}" multiplier="{mult:.10g}" offset="{off:.10g}"/>')
        lines.append("  </joint>")
        self.parts.append("\n".join(lines))
        self.joints[child] = {"name": name, "parent": parent, "xyz": xyz, "rpy": rpy, "axis": axis}

    def text(self, header: str) -> str:
        mats = "\n".join(
            f'  <material name="{n}"><color rgba="{fmt(c)}"/></material>' for n, c in MATERIALS.items()
        )
        return (
            '<?xml version="1.0" encoding="utf-8"?>\n'
            + header
            + '<robot name="yumi">\n'
            + mats
            + "\n"
            + "\n".join(self.parts)
            + "\n</robot>\n"
        )

    def pose(self, link: str, q: dict[str, float] | None = None) -> np.ndarray:
        """T_root_link from the recorded joints (revolute about their axis by q[name], default 0)."""
        q = q or {}
        t = np.eye(4)
        chain = []
        while link in self.joints:
            chain.append(self.joints[link])
            link = self.joints[link]["parent"]
        for j in reversed(chain):
            t = t @ transform(j["xyz"], j["rpy"])
            angle = q.get(j["name"], 0.0)
            if j["axis"] is not None and angle != 0.0:
                a = np.asarray(j["axis"], dtype=float)
                kx = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
                r = np.eye(4)
                r[:3, :3] = np.eye(3) + math.sin(angle) * kx + (1 - math.cos(angle)) * kx @ kx
                t = t @ r
        return t


def tube(p0, p1, radius, material, collide=True) -> tuple:
    """A cylinder from point p0 to p1 (link frame)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    return ("cylinder", (radius, float(np.linalg.norm(p1 - p0))), tuple((p0 + p1) / 2), align_z_rpy(p1 - p0), material, collide)


def housing(radius, length, material="yumi_dark", xyz=(0, 0, 0), rpy=(0, 0, 0)) -> tuple:
    """A joint housing: a cylinder along the local z axis (the joint axis)."""
    return ("cylinder", (radius, length), xyz, rpy, material, True)


# --------------------------------------------------------------------------- builders
def arm_link(s: str, k: int) -> str:
    return f"yumi_link_{k}_{s}"


def hand(s: str, part: str) -> str:
    return f"yumi_hand_{s}_{part}"


def build_arm(u: Urdf, s: str) -> None:
    parent = "yumi_body"
    for index, (num, xyz, rpy, lo, hi, vel, eff) in enumerate(ARM_CHAIN):
        if num == 1 and s == "r":
            xyz, rpy = JOINT1_RIGHT
        child = arm_link(s, index + 1)
        u.joint(f"yumi_joint_{num}_{s}", "revolute", parent, child, xyz, rpy, (0, 0, 1), (lo, hi, vel, eff))
        parent = child
    # Geometry per link: the joint housing at the frame origin (along the joint
    # axis) and a tube to the next joint's origin.
    nxt = [c[1] for c in ARM_CHAIN[1:]] + [FLANGE_XYZ]
    for index in range(7):
        shapes = [housing(R_JOINT if index < 4 else 0.042, 0.09 if index < 4 else 0.075)]
        if np.linalg.norm(nxt[index]) > 1e-9:
            shapes.append(tube((0, 0, 0), nxt[index], R_ARM if index < 4 else 0.04, "yumi_grey"))
        if index == 6:
            shapes = [housing(0.037, 0.014, "yumi_dark", xyz=(0, 0, 0.0))]
        u.link(arm_link(s, index + 1), shapes)


def build_hand(u: Urdf, s: str) -> None:
    """Inspire RH56 on the flange of yumi_link_7_s; the left hand mirrors the right one."""
    mx = (lambda v: v) if s == "r" else mirror_xyz
    mr = (lambda v: v) if s == "r" else mirror_rpy
    ma = (lambda v: v) if s == "r" else mirror_axis
    flange, base = hand(s, "flange"), hand(s, "base")
    u.joint(f"yumi_hand_{s}_flange_joint", "fixed", arm_link(s, 7), flange, FLANGE_XYZ, FLANGE_RPY)
    u.link(flange)
    u.joint(f"yumi_hand_{s}_mount_joint", "fixed", flange, base, (0, 0, 0), HAND_MOUNT_RPY[s])
    # Palm: a wrist adapter cylinder and the palm box (right-hand base frame, mirrored for the left).
    u.link(
        base,
        [
            tube(mx((0, 0.0, 0)), mx((0, -0.045, 0)), 0.03, "hand_blue"),
            ("box", (0.032, 0.09, 0.072), mx((-0.003, -0.09, -0.003)), (0, 0, 0), "hand_blue", True),
        ],
    )
    # Four fingers: proximal (actuated) and intermediate (coupled) joints, fixed tip frame.
    for finger, (knuckle, roll, mid, tip) in FINGERS.items():
        prox, inter, tipl = hand(s, f"{finger}_proximal"), hand(s, f"{finger}_intermediate"), hand(s, f"{finger}_tip")
        lo, hi = FINGER_PROXIMAL_LIMITS
        mult, off = FINGER_MIMIC
        u.joint(f"yumi_hand_{s}_{finger}_proximal_joint", "revolute", base, prox, mx(knuckle), mr((roll, 0, 0)),
                ma((0, 0, 1)), (lo, hi, HAND_VELOCITY, HAND_EFFORT))
        u.link(prox, [tube(mx((0, 0, -0.005)), mx((mid[0], mid[1], -0.005)), R_FINGER, "finger_black")])
        ilo, ihi = mimic_limits(lo, hi, mult, off)
        u.joint(f"yumi_hand_{s}_{finger}_intermediate_joint", "revolute", prox, inter, mx(mid), (0, 0, 0),
                ma((0, 0, 1)), (ilo, ihi, HAND_VELOCITY, HAND_EFFORT),
                mimic=(f"yumi_hand_{s}_{finger}_proximal_joint", mult, off))
        u.link(inter, [tube(mx((0, 0, -0.004)), mx((tip[0], tip[1] - R_FINGER, tip[2])), R_FINGER, "finger_black"),
                       ("sphere", (R_FINGER,), mx((tip[0], tip[1] - R_FINGER, tip[2])), (0, 0, 0), "finger_black", True)])
        u.joint(f"yumi_hand_{s}_{finger}_tip_joint", "fixed", inter, tipl, mx(tip), (0, 0, 0))
        u.link(tipl)
    # Thumb: yaw (actuated), pitch (actuated), intermediate and distal (coupled to pitch).
    yaw_l, prox_l = hand(s, "thumb_proximal_base"), hand(s, "thumb_proximal")
    inter_l, dist_l, tip_l = hand(s, "thumb_intermediate"), hand(s, "thumb_distal"), hand(s, "thumb_tip")
    (yxyz, yrpy, (ylo, yhi)), (pxyz, prpy, (plo, phi)) = THUMB_YAW, THUMB_PITCH
    yaw_j, pitch_j = f"yumi_hand_{s}_thumb_proximal_yaw_joint", f"yumi_hand_{s}_thumb_proximal_pitch_joint"
    u.joint(yaw_j, "revolute", base, yaw_l, mx(yxyz), mr(yrpy), ma((0, 0, -1)), (ylo, yhi, HAND_VELOCITY, HAND_EFFORT))
    u.link(yaw_l, [("sphere", (0.011,), (0, 0, 0), (0, 0, 0), "finger_black", True)])
    u.joint(pitch_j, "revolute", yaw_l, prox_l, mx(pxyz), mr(prpy), ma((0, 0, 1)), (plo, phi, HAND_VELOCITY, HAND_EFFORT))
    u.link(prox_l, [tube(mx((0, 0, -0.006)), mx((THUMB_INTERMEDIATE_XYZ[0], THUMB_INTERMEDIATE_XYZ[1], -0.006)),
                         0.01, "finger_black")])
    mult, off = THUMB_INTERMEDIATE_MIMIC
    ilo, ihi = mimic_limits(plo, phi, mult, off)
    u.joint(f"yumi_hand_{s}_thumb_intermediate_joint", "revolute", prox_l, inter_l, mx(THUMB_INTERMEDIATE_XYZ),
            (0, 0, 0), ma((0, 0, 1)), (ilo, ihi, HAND_VELOCITY, HAND_EFFORT), mimic=(pitch_j, mult, off))
    u.link(inter_l, [tube(mx((0, 0, -0.006)), mx((THUMB_DISTAL_XYZ[0], THUMB_DISTAL_XYZ[1], -0.006)), R_FINGER,
                          "finger_black")])
    mult, off = THUMB_DISTAL_MIMIC
    dlo, dhi = mimic_limits(plo, phi, mult, off)
    u.joint(f"yumi_hand_{s}_thumb_distal_joint", "revolute", inter_l, dist_l, mx(THUMB_DISTAL_XYZ), (0, 0, 0),
            ma((0, 0, 1)), (dlo, dhi, HAND_VELOCITY, HAND_EFFORT), mimic=(pitch_j, mult, off))
    tip_end = (THUMB_TIP_XYZ[0] * 0.8, THUMB_TIP_XYZ[1] * 0.8, -0.006)
    u.link(dist_l, [tube(mx((0, 0, -0.006)), mx(tip_end), R_FINGER, "finger_black"),
                    ("sphere", (R_FINGER,), mx(tip_end), (0, 0, 0), "finger_black", True)])
    u.joint(f"yumi_hand_{s}_thumb_tip_joint", "fixed", dist_l, tip_l, mx(THUMB_TIP_XYZ), (0, 0, 0))
    u.link(tip_l)


def mimic_limits(lo: float, hi: float, mult: float, off: float) -> tuple[float, float]:
    """Limits of a coupled joint that hold the formula's whole range over the source's range.

    Rounded outwards to 0.01 rad (the formula's end values lie inside or on them).
    """
    a, b = sorted((mult * lo + off, mult * hi + off))
    return (math.floor(a * 100) / 100, math.ceil(b * 100) / 100)


# --------------------------------------------------------------------------- spec
ARM_ORDER = (1, 2, 7, 3, 4, 5, 6)
HAND_ORDER = ("thumb_proximal_yaw", "thumb_proximal_pitch", "index_proximal", "middle_proximal", "ring_proximal",
              "pinky_proximal")
# Roles (link frames of the published chain): shoulder = joint 2's frame,
# elbow = joint 3's frame, wrist = joint 6's frame (the flange).
ROLE_LINKS = {"shoulder": 2, "elbow": 4, "wrist": 7}


def actuated_joints() -> list[str]:
    names = [f"yumi_joint_{k}_{s}" for s in SIDES for k in ARM_ORDER]
    names += [f"yumi_hand_{s}_{j}_joint" for s in SIDES for j in HAND_ORDER]
    return names


def wrist_alignment(u: Urdf, s: str) -> np.ndarray:
    """R_wristlink_handframe from the finger geometry (fixed: every link involved is rigid w.r.t. link_7)."""
    t_w = u.pose(arm_link(s, 7))
    inv = np.linalg.inv(t_w)
    p = {n: (inv @ u.pose(hand(s, n)))[:3, 3] for n in ("base", "middle_proximal", "index_proximal", "pinky_proximal")}
    x = p["middle_proximal"] - p["base"]
    x /= np.linalg.norm(x)
    y = p["index_proximal"] - p["pinky_proximal"]
    y -= (y @ x) * x
    y /= np.linalg.norm(y)
    return np.stack([x, y, np.cross(x, y)], axis=1)


# A collision-free neutral pose (deg): elbows lowered beside the body, forearms
# forward, hands in front pointing forward with the palms facing each other. Right arm: joint 1's frame mirrors the left one's with the
# rotation sense reversed, so joints 1, 7, 4 and 6 change sign.
NEUTRAL_DEG = {1: -100.0, 2: -120.0, 7: 40.0, 3: 50.0, 4: 10.0, 5: -35.0, 6: -120.0}


# Joint velocity limits [rad/s]. Arms: the `velocity` of each joint's <limit> in yumi_description
# (Örebro University, BSD-2): axes 1, 2, 7, 3 at 180 deg/s, axes 4-6 at 400 deg/s.
# Hands: we found no published joint-speed figure for the Inspire RH56 (the vendor page only says
# "moderate speed"); ASSUMED 2.0 rad/s for every actuated hand joint (a full 1.47 rad finger stroke
# in about 0.75 s).
ARM_VELOCITY = {"1": 3.1416, "2": 3.1416, "7": 3.1416, "3": 3.1416, "4": 6.9813, "5": 6.9813, "6": 6.9813}
HAND_VELOCITY_ASSUMED = HAND_VELOCITY
VELOCITY_SOURCE = (
    "arms: yumi_description (Orebro University, BSD-2) joint <limit velocity>; "
    "Inspire RH56 hand joints: no published figure found, 2.0 rad/s assumed"
)


def velocity_limits() -> dict[str, float]:
    """Published arm joint speeds, the assumed hand joint speed (see ARM_VELOCITY)."""
    out = {}
    for name in actuated_joints():
        if name.startswith("yumi_joint_"):
            out[name] = ARM_VELOCITY[name.split("_")[2]]
        else:
            out[name] = HAND_VELOCITY_ASSUMED
    return out


def neutral_pose() -> dict[str, float]:
    flip = {1, 7, 4, 6}
    q = {}
    for s in SIDES:
        for k in ARM_ORDER:
            v = math.radians(NEUTRAL_DEG[k])
            q[f"yumi_joint_{k}_{s}"] = -v if (s == "r" and k in flip) else v
    for s in SIDES:
        for j in HAND_ORDER:
            q[f"yumi_hand_{s}_{j}_joint"] = 0.0
    return {k: round(v, 6) for k, v in q.items()}


# --------------------------------------------------------------------------- main
def build() -> tuple[str, dict]:
    # First pass with the published base offset: measure the shoulders.
    def assemble(world_xyz) -> Urdf:
        u = Urdf()
        u.link("world")
        u.joint("world_joint", "fixed", "world", "yumi_base_link", world_xyz, (0, 0, 0))
        u.link("yumi_base_link")
        u.joint("yumi_base_link_to_body", "fixed", "yumi_base_link", "yumi_body", (0, 0, 0), (0, 0, 0))
        u.link(
            "yumi_body",
            [
                ("box", (0.24, 0.30, 0.10), (-0.06, 0.0, 0.05), (0, 0, 0), "yumi_body", True),  # foot
                ("box", (0.17, 0.20, 0.36), (-0.055, 0.0, 0.27), (0, 0, 0), "yumi_body", True),  # torso
                ("box", (0.10, 0.26, 0.10), (0.0, 0.0, 0.41), (0, 0, 0), "yumi_body", True),  # shoulder block
            ],
        )
        for s in SIDES:
            build_arm(u, s)
            build_hand(u, s)
        return u

    published = (0.0, 0.0, 0.1)
    u0 = assemble(published)
    mid = 0.5 * (u0.pose(arm_link("l", 2))[:3, 3] + u0.pose(arm_link("r", 2))[:3, 3])
    world_xyz = tuple(round(float(v), 8) for v in np.asarray(published) - mid)
    u = assemble(world_xyz)

    arms = {}
    for s in SIDES:
        rpy = rpy_of(wrist_alignment(u, s))
        arms[SIDE_NAMES[s]] = {
            "shoulder": arm_link(s, ROLE_LINKS["shoulder"]),
            "elbow": arm_link(s, ROLE_LINKS["elbow"]),
            "wrist": arm_link(s, ROLE_LINKS["wrist"]),
            "wrist_alignment_rpy": [round(v, 9) for v in rpy],
            "fingers": {
                "thumb": [hand(s, "thumb_proximal"), hand(s, "thumb_tip")],
                **{f: [hand(s, f"{f}_proximal"), hand(s, f"{f}_tip")] for f in ("index", "middle", "ring", "pinky")},
            },
        }
    spec = {
        "name": "yumi",
        "urdf": "yumi.urdf",
        "base_link": "world",
        "actuated_joints": actuated_joints(),
        "arms": arms,
        "capsules": [],  # fitted to the URDF's collision geometry by fit_capsules.py (main() runs it)
        "collision_pairs": [],
        "collision_margin": {"default": 0.005},
        "neutral_pose": neutral_pose(),
        "velocity_limits": velocity_limits(),
        "velocity_limits_source": VELOCITY_SOURCE,
    }
    header = (
        "<!-- ABB YuMi (IRB 14000) with two Inspire RH56 hands, primitive geometry only.\n"
        "     GENERATED by assets/robots/make_yumi_urdf.py: do not edit by hand; regenerate with\n"
        "       .venv/bin/python assets/robots/make_yumi_urdf.py\n"
        "     Sources and choices: assets/robots/YUMI.md.\n"
        f"     world -> yumi_base_link offset {fmt(world_xyz)} puts the midpoint of the two shoulder\n"
        "     frames (yumi_link_2_l/r) at the origin at the zero pose (published offset: 0 0 0.1). -->\n"
    )
    return u.text(header), spec


def main() -> None:
    text, spec = build()
    URDF_PATH.write_text(text, encoding="utf-8")
    SPEC_PATH.write_text(json.dumps(spec, indent=2) + "\n", encoding="utf-8")
    fit_capsules.update("yumi")  # capsules and pairs fitted to the collision geometry just written
    print(f"wrote {URDF_PATH.name} and {SPEC_PATH.name}")
    for side, arm in spec["arms"].items():
        print(side, "wrist_alignment_rpy", arm["wrist_alignment_rpy"])


if __name__ == "__main__":
    main()
