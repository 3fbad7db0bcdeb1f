"""The robot's structure graph, the decoder's skeleton.

Nodes are the actuated joints; an edge goes from each joint's nearest actuated
ancestor to the joint (parent -> child, as in the paper). Mimic joints are not
nodes (their angle follows their source). The first joint of each arm has no
actuated ancestor; instead of a virtual root node (which would add a node
without an angle), the arm roots are joined to each other by one edge in each
direction, so that every node receives messages and the two arms can
coordinate (the collision term couples them). Edge features are the child
joint's origin (xyz [m], rpy [rad]) relative to the parent joint's frame, fixed
joints in between folded in; for the root-to-root edges, the child root's frame
relative to the other root's frame. Finger joints (below a wrist link) are
hand nodes, the others arm nodes.
"""

from __future__ import annotations

import numpy as np
import torch

from nlo_lab.graph import NODE_ARM, NODE_HAND, Graph
from nlo_lab.robot.kinematics import KinematicTree
from nlo_lab.robot.spec import RobotSpec
from nlo_lab.robot.urdf import URDFModel
from nlo_lab.rotations import matrix_to_rpy

__all__ = ["structure_graph"]


def structure_graph(spec: RobotSpec, model: URDFModel, tree: KinematicTree) -> Graph:
    """The structure graph of ``spec.actuated_joints`` in float64 (see the module docstring)."""
    joint_names = list(spec.actuated_joints)
    joints = {j.name: j for j in model.joints}
    act = {n: i for i, n in enumerate(joint_names)}
    moving_idx = {n: k for k, n in enumerate(tree.moving_names)}
    pre = tree.moving_pre  # (M, 4, 4) T_parentbody_joint

    def actuated_parent(name: str) -> tuple[int, np.ndarray]:
        """Nearest actuated ancestor (node index or -1) and T_ancestorframe_jointframe."""
        T = pre[moving_idx[name]]
        k = tree.moving_parent[moving_idx[name]]
        while k >= 0:
            pname = tree.moving_names[k]
            if pname in act:
                return act[pname], T
            T = pre[k] @ T  # a mimic joint in between: at its zero angle
            k = tree.moving_parent[k]
        return -1, T

    edges, attrs, roots = [], [], []
    for name in joint_names:
        p, T = actuated_parent(name)
        if p < 0:
            roots.append((act[name], T))
        else:
            edges.append((p, act[name]))
            attrs.append(np.concatenate([T[:3, 3], matrix_to_rpy(T[:3, :3])]))
    for i, Ti in roots:  # arm roots joined both ways (see the module docstring)
        for j, Tj in roots:
            if i != j:
                Tij = np.linalg.inv(Ti) @ Tj
                edges.append((i, j))
                attrs.append(np.concatenate([Tij[:3, 3], matrix_to_rpy(Tij[:3, :3])]))
    hands = _hand_joints(spec, model, joints)
    node_type = [NODE_HAND if n in hands else NODE_ARM for n in joint_names]
    return Graph(
        tuple(joint_names),
        torch.tensor(edges, dtype=torch.long).reshape(-1, 2).T.contiguous(),
        torch.as_tensor(np.array(attrs).reshape(-1, 6)),
        torch.tensor(node_type, dtype=torch.long),
    )


def _hand_joints(spec: RobotSpec, model: URDFModel, joints: dict) -> set[str]:
    """Actuated joints below a wrist link (finger joints) are hand nodes."""
    has_fingers = any(arm.fingers for arm in spec.arms.values())
    wrists = {arm.wrist for arm in spec.arms.values()} if has_fingers else set()
    out = set()
    for name in spec.actuated_joints:
        link = joints[name].parent
        while link is not None:
            if link in wrists:
                out.add(name)
                break
            pj = model.parent_joint(link)
            link = None if pj is None else pj.parent
    return out
