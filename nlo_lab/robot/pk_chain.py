"""A robot as a pytorch-kinematics chain: the field's reference forward kinematics.

pytorch-kinematics (``pytorch_kinematics``) is what robotics users reach for to
get differentiable FK from a URDF. Our own FK (:mod:`nlo_lab.robot.kinematics`) must
agree with it on every robot (``tests/robot/test_kinematics.py``), and notebook 01
runs the two side by side::

    from nlo_lab.robot.pk_chain import PKChain
    ref = PKChain(robot)                  # the chain of the robot's URDF
    poses = ref.forward_kinematics(q)     # q (..., n) in robot.joint_names order -> {link: (..., 4, 4)}
    ref.chain                             # the pytorch_kinematics.Chain itself
    ref.angles(q)                         # (..., n_pk) in ref.chain.get_joint_parameter_names() order

pytorch-kinematics treats every moving joint as independent; it does not read
``<mimic>``. :meth:`PKChain.angles` therefore expands our actuated angles to
every moving joint the URDF's way (``multiplier * q_source + offset``), as our
FK does internally.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import torch

if TYPE_CHECKING:  # annotations only: no import at run time
    from nlo_lab.robot.robot import Robot

__all__ = ["PKChain"]


class PKChain:
    """The robot's URDF as a ``pytorch_kinematics`` chain, fed with our angle vector.

    Args:
        robot: a :class:`nlo_lab.robot.Robot`.
        dtype: the chain's dtype (default: the robot's).
    """

    def __init__(self, robot: Robot, dtype: torch.dtype | None = None):
        import pytorch_kinematics as pk  # the reference: imported only where it is used

        self.robot = robot
        self.dtype = dtype or robot.lower_limits.dtype
        # pytorch-kinematics reads the URDF text itself: an independent second reader is what a reference is for.
        self.chain = pk.build_chain_from_urdf(robot.spec.urdf.read_bytes()).to(dtype=self.dtype)
        self.joint_names: list[str] = list(self.chain.get_joint_parameter_names())
        moving = {name: k for k, name in enumerate(robot.tree.moving_names)}
        self._order = torch.tensor([moving[name] for name in self.joint_names])

    def angles(self, q: torch.Tensor) -> torch.Tensor:
        """Our actuated angles ``(..., n)`` -> the chain's joint vector ``(..., n_pk)`` (mimic joints expanded)."""
        q = torch.as_tensor(q, dtype=self.dtype)
        return self.robot.tree.joint_angles(q).index_select(-1, self._order)

    def forward_kinematics(self, q: torch.Tensor) -> dict[str, torch.Tensor]:
        """``{link: T_root_link (..., 4, 4)}`` of every link the chain has."""
        q = torch.as_tensor(q, dtype=self.dtype)
        lead = q.shape[:-1]
        frames = self.chain.forward_kinematics(self.angles(q.reshape(-1, q.shape[-1])))
        return {name: tf.get_matrix().reshape(*lead, 4, 4) for name, tf in frames.items()}
