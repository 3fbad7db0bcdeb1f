"""The robot side: spec and URDF, kinematic tree, collision capsules and the structure graph.

::

    from nlo_lab.robot import load_robot
    robot = load_robot("yumi")               # or "nao", "pepper", or a spec .json
    poses = robot.forward_kinematics(q)      # q (B, n) [rad] -> {link: (B, 4, 4)}
    d = robot.capsule_distances(poses)       # (B, P) [m], < 0 = penetration

Modules, along the data's path: :mod:`~nlo_lab.robot.spec` (the spec file),
:mod:`~nlo_lab.robot.urdf` (the URDF, checked), :mod:`~nlo_lab.robot.kinematics`
(batched FK) with :mod:`~nlo_lab.robot.point_gradient` (its written-out gradient),
:mod:`~nlo_lab.robot.collision` (segment and capsule distances),
:mod:`~nlo_lab.robot.structure_graph`, :mod:`~nlo_lab.robot.robot` (``Robot``) and
:mod:`~nlo_lab.robot.pk_chain` (pytorch-kinematics as the reference FK). The link geometry:
:mod:`~nlo_lab.robot.safe_xml` (XML without entities), :mod:`~nlo_lab.robot.mesh_files`
(mesh paths confined to the URDF's folder tree, bounded sizes), :mod:`~nlo_lab.robot.geometry`
(visual and collision shapes as meshes), :mod:`~nlo_lab.robot.geometry_collision` (self-collision
by the URDF's own geometry), :mod:`~nlo_lab.robot.capsule_fit` and
:mod:`~nlo_lab.robot.capsule_draft` (capsules and checked pairs fitted to that geometry).
A robot of one's own: :mod:`~nlo_lab.robot.fixed_joints` (joints not actuated fixed, the robot
frame at the root), :mod:`~nlo_lab.robot.arm_finder`, :mod:`~nlo_lab.robot.wrist_alignment`,
:mod:`~nlo_lab.robot.spec_draft` (``nlo-lab robot init``), :mod:`~nlo_lab.robot.spec_check`
(``nlo-lab robot check``) and :mod:`~nlo_lab.robot.srdf`. A trajectory against the robot:
:mod:`~nlo_lab.robot.speeds` (joint speeds over the velocity limits; retiming and the metrics read them).
"""

from nlo_lab.robot.collision import capsule_distance, closest_parameters, segment_distance, segment_distance_ends
from nlo_lab.robot.geometry import Shape, link_shapes, shape_mesh
from nlo_lab.robot.geometry_collision import GeometryCollision
from nlo_lab.robot.kinematics import KinematicTree
from nlo_lab.robot.robot import Robot, as_robot, check_angles, load_robot
from nlo_lab.robot.spec import ArmSpec, CapsuleSpec, RobotSpec, known_robots, load_spec
from nlo_lab.robot.spec_check import check_spec, spec_summary
from nlo_lab.robot.spec_draft import Draft, draft_spec
from nlo_lab.robot.speeds import joint_speeds, speed_ratios
from nlo_lab.robot.structure_graph import structure_graph
from nlo_lab.robot.urdf import JointInfo, URDFModel, load_urdf, parse_urdf

__all__ = [
    "Robot",
    "load_robot",
    "as_robot",
    "check_angles",
    "ArmSpec",
    "CapsuleSpec",
    "RobotSpec",
    "load_spec",
    "known_robots",
    "KinematicTree",
    "JointInfo",
    "URDFModel",
    "load_urdf",
    "parse_urdf",
    "structure_graph",
    "segment_distance",
    "segment_distance_ends",
    "closest_parameters",
    "capsule_distance",
    "Shape",
    "link_shapes",
    "shape_mesh",
    "GeometryCollision",
    "Draft",
    "draft_spec",
    "check_spec",
    "spec_summary",
    "joint_speeds",
    "speed_ratios",
]
