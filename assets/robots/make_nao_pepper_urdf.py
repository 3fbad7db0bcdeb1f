"""Generate nao.urdf and pepper.urdf (primitive geometry) in the current directory. Run: cd assets/robots && python make_nao_pepper_urdf.py"""
import math


def fmt(v):
    return " ".join(f"{x:.6g}" for x in v)

class U:
    def __init__(self, name):
        self.name = name; self.parts = []
    def link(self, name, geoms=()):
        s = [f'  <link name="{name}">']
        for kind, xyz, rpy, dims, color in geoms:
            if kind == "box": g = f'<box size="{fmt(dims)}"/>'
            elif kind == "cyl": g = f'<cylinder radius="{dims[0]:.6g}" length="{dims[1]:.6g}"/>'
            else: g = f'<sphere radius="{dims[0]:.6g}"/>'
            for tag in ("visual", "collision"):
                mat = f'\n      <material name="{color}"/>' if tag == "visual" else ""
                s.append(f'    <{tag}>\n      <origin xyz="{fmt(xyz)}" rpy="{fmt(rpy)}"/>\n      <geometry>{g}</geometry>{mat}\n    </{tag}>')
        s.append('  </link>')
        self.parts.append("\n".join(s))
    def joint(self, name, typ, parent, child, xyz, rpy=(0, 0, 0), axis=None, limit=None):
        s = [f'  <joint name="{name}" type="{typ}">', f'    <parent link="{parent}"/>', f'    <child link="{child}"/>',
             f'    <origin xyz="{fmt(xyz)}" rpy="{fmt(rpy)}"/>']
        if axis is not None: s.append(f'    <axis xyz="{fmt(axis)}"/>')
        if limit is not None: s.append(f'    <limit lower="{limit[0]}" upper="{limit[1]}" effort="{limit[2]}" velocity="{limit[3]}"/>')
        s.append('  </joint>')
        self.parts.append("\n".join(s))
    def write(self, path, header):
        mats = "\n".join(f'  <material name="{n}"><color rgba="{c}"/></material>' for n, c in
                         [("white", "0.93 0.93 0.93 1"), ("grey", "0.45 0.45 0.5 1"), ("dark", "0.2 0.2 0.22 1"), ("accent", "0.95 0.55 0.1 1")])
        txt = f'<?xml version="1.0"?>\n<!-- {header} -->\n<robot name="{self.name}">\n{mats}\n' + "\n".join(self.parts) + "\n</robot>\n"
        open(path, "w").write(txt)

X = (0, math.pi / 2, 0)  # cylinder (along z) turned to lie along x
Y = (math.pi / 2, 0, 0)

def arm(u, side, sh, lim, up_len, elbow_xyz, elbow_rpy, fore_len, grip_xyz, r_up, r_fore, hand):
    s = 1 if side == "L" else -1
    p = side  # joint-name prefix
    l = side.lower()
    u.joint(f"{p}ShoulderPitch", "revolute", "torso", f"{p}Shoulder", (sh[0], s * sh[1], sh[2]), axis=(0, 1, 0), limit=lim["pitch"])
    u.link(f"{p}Shoulder", [("sph", (0, 0, 0), (0, 0, 0), (r_up * 1.15,), "white")])
    u.joint(f"{p}ShoulderRoll", "revolute", f"{p}Shoulder", f"{p}Bicep", (0, 0, 0), axis=(0, 0, 1), limit=lim[f"{l}roll"])
    u.link(f"{p}Bicep", [("cyl", (up_len / 2, s * elbow_xyz[1] / 2, 0), X, (r_up, up_len), "white")])
    u.joint(f"{p}ElbowYaw", "revolute", f"{p}Bicep", f"{p}Elbow", (elbow_xyz[0], s * elbow_xyz[1], elbow_xyz[2]), elbow_rpy, axis=(1, 0, 0), limit=lim["eyaw"])
    u.link(f"{p}Elbow", [("sph", (0, 0, 0), (0, 0, 0), (r_fore * 1.1,), "grey")])
    u.joint(f"{p}ElbowRoll", "revolute", f"{p}Elbow", f"{p}ForeArm", (0, 0, 0), axis=(0, 0, 1), limit=lim[f"{l}eroll"])
    u.link(f"{p}ForeArm", [("cyl", (fore_len / 2, 0, 0), X, (r_fore, fore_len), "white")])
    u.joint(f"{p}WristYaw", "revolute", f"{p}ForeArm", f"{l}_wrist", (fore_len, 0, 0), axis=(1, 0, 0), limit=lim["wyaw"])
    # Hand: palm plate in the x-y plane (palm side -z), fingers along +x, thumb on the medial side
    # (-y for the left hand, +y for the right) -- the hand is palm-down at the zero pose.
    hl, hw, ht = hand
    u.link(f"{l}_wrist", [("box", (hl / 2, 0, 0), (0, 0, 0), (hl, hw, ht), "dark"),
                          ("sph", (hl * 0.35, -s * hw * 0.55, -ht * 0.2), (0, 0, 0), (ht * 0.6,), "accent")])
    u.joint(f"{p}Hand", "fixed", f"{l}_wrist", f"{l}_gripper", grip_xyz)
    u.link(f"{l}_gripper")

# ---------------------------------------------------------------- NAO V5
LIM = 2.08567
nao = U("nao")
nao.link("world")
nao.joint("world_to_torso", "fixed", "world", "torso", (0, 0, -0.1))
nao.link("torso", [("box", (-0.008, 0, 0.035), (0, 0, 0), (0.085, 0.13, 0.17), "white"),
                   ("cyl", (-0.01, 0, -0.07), (0, 0, 0), (0.05, 0.04), "grey")])
nao.joint("torso_to_legs", "fixed", "torso", "legs", (0, 0, -0.085))
nao.link("legs", [("cyl", (0.0, 0.05, -0.115), (0, 0, 0), (0.035, 0.21), "white"),
                  ("cyl", (0.0, -0.05, -0.115), (0, 0, 0), (0.035, 0.21), "white"),
                  ("box", (0.02, 0.05, -0.225), (0, 0, 0), (0.16, 0.08, 0.045), "grey"),
                  ("box", (0.02, -0.05, -0.225), (0, 0, 0), (0.16, 0.08, 0.045), "grey")])
nao.joint("HeadYaw", "fixed", "torso", "Neck", (0, 0, 0.1265))
nao.link("Neck", [("cyl", (0, 0, 0.01), (0, 0, 0), (0.02, 0.03), "grey")])
nao.joint("HeadPitch", "fixed", "Neck", "Head", (0, 0, 0))
nao.link("Head", [("sph", (0, 0, 0.058), (0, 0, 0), (0.066,), "white")])
lim = {"pitch": (-LIM, LIM, 1.329, 8.26797), "lroll": (-0.314159, 1.32645, 1.7835, 7.19407), "rroll": (-1.32645, 0.314159, 1.7835, 7.19407),
       "eyaw": (-LIM, LIM, 1.547, 8.26797), "leroll": (-1.54462, -0.0349066, 1.532, 7.19407), "reroll": (0.0349066, 1.54462, 1.532, 7.19407),
       "wyaw": (-1.82387, 1.82387, 0.4075, 24.6229)}
for side in "LR":
    arm(nao, side, (0, 0.098, 0.1), lim, 0.105, (0.105, 0.015, 0), (0, 0, 0), 0.05595, (0.05775, 0, -0.01231), 0.024, 0.021, (0.065, 0.045, 0.022))
nao.write("nao.urdf", "NAO V5 arms, torso and head, written by nlo_lab with primitive geometry. "
          "Joint origins, axes and limits: ros-naoqi nao_description (BSD-3); see README.md. "
          "World origin = centre of the two shoulder joints, X forward, Y left, Z up.")

# ---------------------------------------------------------------- Pepper 1.0
pep = U("pepper")
pep.link("world")
pep.joint("world_to_torso", "fixed", "world", "torso", (0.057, 0, -0.08682))
pep.link("torso", [("cyl", (-0.02, 0, -0.01), (0, 0, 0), (0.09, 0.2), "white"),
                   ("box", (-0.045, 0, 0.07), (0, 0, 0), (0.13, 0.26, 0.06), "white"),
                   ("box", (0.05, 0, 0.0), (0, 0, 0), (0.01, 0.1, 0.07), "dark")])
pep.joint("torso_to_base", "fixed", "torso", "base", (0, 0, -0.12))
pep.link("base", [("cyl", (-0.02, 0, -0.2), (0, 0, 0), (0.09, 0.4), "white"),
                  ("cyl", (-0.02, 0, -0.58), (0, 0, 0), (0.22, 0.24), "white")])
pep.joint("HeadYaw", "fixed", "torso", "Neck", (-0.038, 0, 0.1699))
pep.link("Neck", [("cyl", (0, 0, 0.02), (0, 0, 0), (0.035, 0.05), "grey")])
pep.joint("HeadPitch", "fixed", "Neck", "Head", (0, 0, 0))
pep.link("Head", [("sph", (0.0, 0, 0.11), (0, 0, 0), (0.1,), "white"),
                  ("box", (0.085, 0, 0.1), (0, 0, 0), (0.03, 0.12, 0.06), "dark")])
lim = {"pitch": (-LIM, LIM, 2.0, 7.33998), "lroll": (0.00872665, 1.56207, 2.0, 9.22756), "rroll": (-1.56207, -0.00872665, 2.0, 9.22756),
       "eyaw": (-LIM, LIM, 2.0, 7.33998), "leroll": (-1.56207, -0.00872665, 2.0, 9.22756), "reroll": (0.00872665, 1.56207, 2.0, 9.22756),
       "wyaw": (-1.82387, 1.82387, 0.3, 17.3835)}
for side in "LR":
    arm(pep, side, (-0.057, 0.14974, 0.08682), lim, 0.1812, (0.1812, 0.015, 0.00013), (0, -0.157079, 0), 0.15, (0.025, 0, 0), 0.042, 0.034, (0.1, 0.07, 0.03))
pep.write("pepper.urdf", "Pepper 1.0 arms, torso and head, written by nlo_lab with primitive geometry. "
          "Joint origins, axes and limits: ros-naoqi pepper_description (Apache-2.0); see README.md. "
          "World origin = centre of the two shoulder joints, X forward, Y left, Z up.")
