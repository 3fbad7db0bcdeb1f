"""Generate the lesson robot of notebook 10: ``lesson_robot.urdf`` and its meshes (``meshes/*.stl``).

    .venv/bin/python assets/robots/lesson/make_lesson_robot.py

A robot written by nlo_lab for the lesson "Your own robot": a pedestal, a torso and a head on a
neck joint, two 6-joint arms (shoulder pitch, roll and yaw at one point, elbow, wrist yaw and
pitch) and 3-finger hands (thumb, index, middle; the distal joint of each finger follows its
proximal one, a URDF ``<mimic>``). Every link is a mesh made with trimesh (capsules, spheres,
boxes, a few hundred triangles each), referred to by a path relative to the URDF, as a real
robot's description does. It is not a bundled robot (no spec): the notebook drafts one with
``nlo-lab robot init``. The numbers are ours, chosen to look like a small service robot.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent
MESHES = HERE / "meshes"


def capsule(radius: float, length: float, z0: float) -> trimesh.Trimesh:
    """A capsule along Z from ``z0`` down to ``z0 - length`` (its axis; the caps reach radius further)."""
    m = trimesh.creation.capsule(height=length, radius=radius, count=[12, 8])
    m.apply_translation((0, 0, z0 - length / 2))
    return m


def shapes() -> dict[str, trimesh.Trimesh]:
    pedestal = trimesh.util.concatenate([
        trimesh.creation.cylinder(radius=0.26, height=0.04, sections=24, transform=trimesh.transformations.translation_matrix((0, 0, 0.02))),
        trimesh.creation.cylinder(radius=0.07, height=0.62, sections=16, transform=trimesh.transformations.translation_matrix((0, 0, 0.33))),
    ])
    torso = trimesh.util.concatenate([
        trimesh.creation.box(extents=(0.18, 0.30, 0.34), transform=trimesh.transformations.translation_matrix((0, 0, 0.13))),
        trimesh.creation.cylinder(radius=0.09, height=0.06, sections=16, transform=trimesh.transformations.translation_matrix((0, 0, -0.07))),
    ])
    head = trimesh.util.concatenate([
        trimesh.creation.icosphere(subdivisions=2, radius=0.1),
        trimesh.creation.box(extents=(0.03, 0.12, 0.04), transform=trimesh.transformations.translation_matrix((0.09, 0, 0.01))),
    ])
    return {
        "pedestal": pedestal,
        "torso": torso,
        "head": head,
        "shoulder": trimesh.creation.icosphere(subdivisions=2, radius=0.055),
        "upper_arm": capsule(0.045, 0.17, -0.04),
        "forearm": capsule(0.038, 0.15, -0.04),
        "wrist": trimesh.creation.icosphere(subdivisions=1, radius=0.032),
        "palm": trimesh.creation.box(extents=(0.035, 0.08, 0.09), transform=trimesh.transformations.translation_matrix((0, 0, -0.055))),
        "finger": capsule(0.009, 0.028, -0.005),
        "fingertip": capsule(0.008, 0.02, -0.005),
    }


def link(name: str, mesh: str | None = None, xyz=(0, 0, 0)) -> str:
    if mesh is None:
        return f'  <link name="{name}"/>'
    origin = f'<origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}"/>'
    geometry = f'<geometry><mesh filename="meshes/{mesh}.stl"/></geometry>'
    return (f'  <link name="{name}">\n    <visual>{origin}{geometry}</visual>\n'
            f'    <collision>{origin}{geometry}</collision>\n  </link>')


def joint(name: str, kind: str, parent: str, child: str, xyz=(0, 0, 0), axis=None, limit=None, mimic=None) -> str:
    lines = [f'  <joint name="{name}" type="{kind}">', f'    <parent link="{parent}"/><child link="{child}"/>',
             f'    <origin xyz="{xyz[0]:.4g} {xyz[1]:.4g} {xyz[2]:.4g}"/>']
    if axis is not None:
        lines.append(f'    <axis xyz="{axis[0]} {axis[1]} {axis[2]}"/>')
    if limit is not None:
        lines.append(f'    <limit lower="{limit[0]}" upper="{limit[1]}" velocity="{limit[2]}" effort="5"/>')
    if mimic is not None:
        lines.append(f'    <mimic joint="{mimic}" multiplier="1" offset="0"/>')
    lines.append("  </joint>")
    return "\n".join(lines)


def arm(s: str) -> list[str]:
    y = 0.2 if s == "l" else -0.2
    sign = 1 if s == "l" else -1
    roll = (-0.3, 2.6) if s == "l" else (-2.6, 0.3)
    parts = [
        joint(f"{s}_shoulder_pitch", "revolute", "torso", f"{s}_shoulder", (0, y, 0.26), (0, 1, 0), (-3.0, 1.2, 3.0)),
        link(f"{s}_shoulder", "shoulder"),
        joint(f"{s}_shoulder_roll", "revolute", f"{s}_shoulder", f"{s}_shoulder_roll_link", axis=(1, 0, 0), limit=(*roll, 3.0)),
        link(f"{s}_shoulder_roll_link"),
        joint(f"{s}_shoulder_yaw", "revolute", f"{s}_shoulder_roll_link", f"{s}_upper_arm", axis=(0, 0, 1), limit=(-2.0, 2.0, 3.0)),
        link(f"{s}_upper_arm", "upper_arm"),
        joint(f"{s}_elbow", "revolute", f"{s}_upper_arm", f"{s}_forearm", (0, 0, -0.25), (0, 1, 0), (-2.4, 0.0, 3.0)),
        link(f"{s}_forearm", "forearm"),
        joint(f"{s}_wrist_yaw", "revolute", f"{s}_forearm", f"{s}_wrist", (0, 0, -0.23), (0, 0, 1), (-1.8, 1.8, 4.0)),
        link(f"{s}_wrist", "wrist"),
        joint(f"{s}_wrist_pitch", "revolute", f"{s}_wrist", f"{s}_hand", axis=(0, 1, 0), limit=(-1.2, 1.2, 4.0)),
        link(f"{s}_hand", "palm"),
    ]
    # thumb forward of the palm, index and middle along its tip (the hand hangs with the palm facing the body)
    for finger, xyz in (("thumb", (0.03, 0.0, -0.04)), ("index", (0.012, -0.022 * sign, -0.105)), ("middle", (0.012, 0.0, -0.107))):
        base, distal, tip = f"{s}_{finger}_proximal", f"{s}_{finger}_distal", f"{s}_{finger}_tip"
        parts += [
            joint(f"{base}_joint", "revolute", f"{s}_hand", base, xyz, (0, 1, 0), (0.0, 1.5, 2.0)),
            link(base, "finger"),
            joint(f"{distal}_joint", "revolute", base, distal, (0, 0, -0.038), (0, 1, 0), (0.0, 1.5, 2.0), mimic=f"{base}_joint"),
            link(distal, "fingertip"),
            joint(f"{tip}_joint", "fixed", distal, tip, (0, 0, -0.03)),
            link(tip),
        ]
    return parts


def urdf() -> str:
    parts = [
        link("base", "pedestal"),
        joint("torso_joint", "fixed", "base", "torso", (0, 0, 0.72)),
        link("torso", "torso"),
        joint("neck_yaw", "revolute", "torso", "head", (0, 0, 0.42), (0, 0, 1), (-1.0, 1.0, 2.0)),
        link("head", "head"),
        *arm("l"),
        *arm("r"),
    ]
    header = ("<!-- The lesson robot of notebook 10, written by nlo_lab (MIT). GENERATED by make_lesson_robot.py:\n"
              "     do not edit by hand. Meshes: meshes/*.stl, made with trimesh by the same script. -->\n")
    return '<?xml version="1.0"?>\n' + header + '<robot name="lesson_robot">\n' + "\n".join(parts) + "\n</robot>\n"


def main() -> None:
    MESHES.mkdir(exist_ok=True)
    for name, mesh in shapes().items():
        mesh.export(MESHES / f"{name}.stl")
    (HERE / "lesson_robot.urdf").write_text(urdf(), encoding="utf-8")
    print(f"wrote lesson_robot.urdf and {len(shapes())} meshes ({sum(p.stat().st_size for p in MESHES.glob('*.stl')) / 1e3:.0f} kB)")


if __name__ == "__main__":
    np.set_printoptions(precision=4)
    main()
