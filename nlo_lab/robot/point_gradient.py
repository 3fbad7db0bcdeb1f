"""The first derivative of mapped FK points, written out (the fast path of ``map_points``).

:meth:`nlo_lab.robot.kinematics.KinematicTree.map_points` maps points and
directions fixed in links to the world. Autograd differentiates that through
every pose product; for revolute joints the derivative has a closed form (see
:class:`MapPoints`), a dozen batched ops. ``map_points(..., analytic_gradient=True)``
chooses it; the tests hold the two equal. :class:`NumpyPointMap` is the same in numpy, for a descent that
runs without torch (:mod:`nlo_lab.inference.numpy_descent`).
"""

from __future__ import annotations

import numpy as np
import torch
from torch.autograd.function import once_differentiable

__all__ = ["MapPoints", "NumpyPointMap", "left_matmul"]


def left_matmul(A: torch.Tensor, X: torch.Tensor) -> torch.Tensor:
    """``A (m, k) @ X (B, k, c) -> (B, m, c)`` as one 2-d matmul.

    ``A @ X`` broadcasts ``A`` and runs B small matmuls (bmm); folding the batch
    into the columns is one ``(m, k) @ (k, B c)`` product, and so is its backward.
    Measured at B = 170 on YuMi's objective rows (20 x 58, 1 thread): 464 us -> 68 us.
    """
    B, k, c = X.shape
    return (A @ X.transpose(0, 1).reshape(k, B * c)).view(A.shape[0], B, c).transpose(0, 1)


class MapPoints(torch.autograd.Function):
    """:meth:`~nlo_lab.robot.kinematics.KinematicTree.map_points` with the gradient written out.

    For a revolute joint ``j`` with world axis ``a_j`` through ``o_j``, a point
    ``p`` it moves has ``dp/dθ_j = a_j × (p - o_j)`` and a direction ``v`` has
    ``a_j × v``. So ``dL/dθ_j = a_j · (Σ_i p_i × g_i - o_j × Σ_i w_i g_i)`` over
    the vectors the joint moves (``w`` = 1 for points, 0 for directions), then
    ``dL/dq = dL/dθ @ theta_mapᵀ`` through the mimic expansion. A dozen batched
    ops instead of autograd's chain through every pose product; the forward
    runs without recording a graph. First derivatives only.
    """

    @staticmethod
    def points(q: torch.Tensor, tree, body: torch.Tensor, vectors: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The forward without a graph: ``(poses (B, 1+M, 4, 4), points (B, k, 3))``; :meth:`gradient` takes both."""
        with torch.no_grad():
            poses = tree.body_poses(q, tree.fast_compose(q.shape[0]))  # (B, 1+M, 4, 4)
            pts = (poses.index_select(1, body)[..., :3, :] @ vectors[:, :, None])[..., 0]  # (B, k, 3); 4x faster than mul + sum at B 170
        return poses, pts

    @staticmethod
    @torch.no_grad()
    def gradient(g: torch.Tensor, poses: torch.Tensor, pts: torch.Tensor, tree, body: torch.Tensor, vectors: torch.Tensor,
                 columns: torch.Tensor | None = None) -> torch.Tensor:
        """``(B, n)``: the gradient of ``sum(g * points)`` in ``q``, from :meth:`points`' results.

        ``columns``: the indices of the points whose ``g`` may be non-zero (the others are 0 in every frame); the sums
        then run over those alone. A latent optimisation's terms reach a third of the points it maps (the capsule
        ends of the pairs that are near, the rows' points): YuMi, the 4 recordings of ``benchmarks/hands.py``, 25-71
        of 174."""
        D = tree.moved_by(body).to(g.dtype)  # (M, k)
        if columns is not None:
            D, g, pts, vectors = D.index_select(1, columns), g.index_select(1, columns), pts.index_select(1, columns), vectors.index_select(0, columns)
        axis = tree.joint_axes(g.device, g.dtype)  # (M, 3)
        R, o = poses[:, 1:, :3, :3], poses[:, 1:, :3, 3]  # (B, M, 3, 3), (B, M, 3)
        # (B, M, 3) world axes R a, the product written out over its 3 columns: the same sums as the batched matmul's,
        # bit for bit, at a third of its time (YuMi's hands, 97 frames: 61 -> 27 us)
        a = R[..., 0] * axis[:, None, 0] + R[..., 1] * axis[:, None, 1] + R[..., 2] * axis[:, None, 2]
        s1 = left_matmul(D, torch.linalg.cross(pts, g))  # (B, M, 3)
        s0 = left_matmul(D, g * vectors[:, 3:])  # points only
        dtheta = (a * (s1 - torch.linalg.cross(o, s0))).sum(-1)  # (B, M)
        return dtheta @ tree.angle_map(g.device, g.dtype).T

    @staticmethod
    def forward(ctx, q, tree, body, vectors):
        poses, pts = MapPoints.points(q, tree, body, vectors)
        ctx.tree, ctx.body = tree, body
        ctx.save_for_backward(poses, pts, vectors)
        return pts

    @staticmethod
    @once_differentiable  # a second derivative raises instead of coming out wrong
    def backward(ctx, g):
        poses, pts, vectors = ctx.saved_tensors
        return MapPoints.gradient(g, poses, pts, ctx.tree, ctx.body, vectors), None, None, None


_NEXT, _AFTER = [1, 2, 0], [2, 0, 1]


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a × b`` over the last axis, ``(a_y b_z - a_z b_y, ...)``: 13 us where np.cross takes 30 at these sizes."""
    return a[..., _NEXT] * b[..., _AFTER] - a[..., _AFTER] * b[..., _NEXT]


class NumpyPointMap:
    """:class:`MapPoints` in numpy, forward and backward: for the few frames of a numpy descent.

    The same arithmetic as ``map_points(analytic_gradient=True)``: local transforms linear in
    ``[sin θ | cos θ]``, the chain by pointer jumping, then the vectors; the gradient as in
    :class:`MapPoints`. Arrays in ``dtype`` throughout.

    Args:
        tree: the robot's :class:`~nlo_lab.robot.kinematics.KinematicTree`.
        body: ``(k,)`` body index of each vector (:meth:`~nlo_lab.robot.kinematics.KinematicTree.point_map`).
        vectors: ``(k, 4)`` homogeneous vectors in those bodies.
        dtype: numpy dtype of the angles and points.
    """

    def __init__(self, tree, body: np.ndarray, vectors: np.ndarray, dtype):
        c = tree.numpy_constants()
        theta_map = c["theta_map"]
        self.dtype = np.dtype(dtype)
        self.theta_map2 = np.concatenate([theta_map, theta_map], 1).astype(self.dtype)  # sin(θ + π/2) = cos θ
        self.off2 = np.concatenate([c["off"], c["off"] + np.pi / 2]).astype(self.dtype)
        self.local_const = c["local_const"].astype(self.dtype)
        self.local_coef = c["local_coef"].astype(self.dtype)
        self.jumps = c["jumps"]
        self.body = np.asarray(body, dtype=np.int64)
        self.vectors = np.asarray(vectors, dtype=self.dtype)[:, :, None]  # (k, 4, 1)
        self.is_point = np.asarray(vectors, dtype=self.dtype)[:, 3:]  # (k, 1): w = 1 points, 0 directions
        self.moved_by = tree.moved_by(torch.as_tensor(self.body)).numpy().astype(self.dtype)  # (M, k)
        self.axis = np.asarray(tree.joint_axes(torch.device("cpu"), torch.float64).numpy(), dtype=self.dtype)[:, :, None]
        self.theta_map_t = np.ascontiguousarray(theta_map.T, dtype=self.dtype)  # (M, n)

    def forward(self, q: np.ndarray):
        """``q (B, n)`` -> points ``(B, k, 3)`` and what the backward needs."""
        B = q.shape[0]
        sc = np.sin(q @ self.theta_map2 + self.off2)  # (B, 2M)
        T = (self.local_const + sc @ self.local_coef).reshape(B, -1, 4, 4)  # T_parent_body
        for anc in self.jumps:
            T = np.matmul(T[:, anc], T)
        pts = np.matmul(T[:, self.body, :3, :], self.vectors)[..., 0]
        return pts, (T, pts)

    def backward(self, g: np.ndarray, state) -> np.ndarray:
        """Gradient ``(B, n)`` of ``sum(g * points)`` with respect to ``q``."""
        T, pts = state
        a = np.matmul(T[:, 1:, :3, :3], self.axis)[..., 0]  # (B, M, 3) world axes
        s1 = np.matmul(self.moved_by, _cross(pts, g))  # (B, M, 3)
        s0 = np.matmul(self.moved_by, g * self.is_point)
        dtheta = (a * (s1 - _cross(T[:, 1:, :3, 3], s0))).sum(-1)  # (B, M)
        return dtheta @ self.theta_map_t
