"""Batched, differentiable forward kinematics of a URDF tree.

:class:`KinematicTree` takes a parsed URDF (:func:`nlo_lab.robot.urdf.parse_urdf`)
and precomputes, per moving joint, the index of its nearest moving ancestor, the
fixed transform from that ancestor's frame to the joint (fixed joints are folded
in), its axis and its mimic rule. One forward pass (:meth:`KinematicTree.body_poses`) is

1. the angles of every moving joint (mimic: ``m * q_src + c``) as one matmul,
2. every local transform ``T_parentbody_body = pre @ Rodrigues(axis, theta)``
   from one matmul on ``[sin theta | cos theta]`` (Rodrigues is linear in sin
   and cos, so the constants ``pre``, ``pre K``, ``pre K^2`` are folded in),
3. chaining, level by level ``T_root_body = T_root_parent @ T_parent_body`` (the
   readable form, the default), or the same product by pointer jumping
   (``ceil(log2(depth + 1))`` batched matmuls; per-op overhead dominates at small
   batch: ``body_poses(q, compose="jumps")``),
4. links = (their body's world frame) @ (a constant), one batched matmul.

The objective does not need every link: :meth:`KinematicTree.map_points` maps
constant points and directions given in link frames to the world with one
gather and one matmul after step 3; autograd differentiates it, or with
``analytic_gradient=True`` the closed-form derivative of
:class:`~nlo_lab.robot.point_gradient.MapPoints` (a faster evaluation of the same
gradient, which also composes by pointer jumping at small sizes, see :data:`JUMP_MAX_WORK`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import torch

from nlo_lab.errors import RobotDescriptionError, SettingsError, SettingsTypeError
from nlo_lab.robot.point_gradient import MapPoints
from nlo_lab.robot.urdf import JointInfo, URDFModel

__all__ = ["KinematicTree", "COMPOSE_FORMS", "JUMP_MAX_WORK"]

COMPOSE_FORMS = ("levels", "jumps")
# batch x tree depth up to which the analytic-gradient path composes by pointer jumping
# (few small matmuls; level by level composes each body once, which wins at large batch)
JUMP_MAX_WORK = 128


class KinematicTree:
    """Precomputed index tensors of a URDF tree and its batched FK.

    Args:
        model: the parsed URDF.
        actuated: names of the actuated joints, the order of the angle vector
            ``q``. Every moving joint must be actuated or mimic an actuated
            joint (directly or through other mimic joints).

    Raises:
        RobotDescriptionError: an actuated name that is not a moving non-mimic
            joint, or a moving joint that is neither actuated nor a mimic.
    """

    def __init__(self, model: URDFModel, actuated: Sequence[str]):
        self.model = model
        path = model.path
        joints = {j.name: j for j in model.joints}
        self.actuated = tuple(actuated)
        if len(set(self.actuated)) != len(self.actuated):
            raise RobotDescriptionError(f"{path}: actuated joints listed twice: {sorted({a for a in actuated if list(actuated).count(a) > 1})}")
        for name in self.actuated:
            j = joints.get(name)
            if j is None:
                raise RobotDescriptionError(f"{path}: actuated joint {name!r} does not exist in the URDF")
            if not j.moving or j.mimic is not None:
                raise RobotDescriptionError(f"{path}: actuated joint {name!r} is {'a mimic' if j.mimic else j.type} joint")
        act_index = {n: i for i, n in enumerate(self.actuated)}

        def resolve(j: JointInfo, depth: int = 0) -> tuple[int, float, float]:
            """(actuated index, multiplier, offset) of a moving joint."""
            if depth > len(joints):
                raise RobotDescriptionError(f"{path}: mimic joints form a cycle at {j.name!r}")
            if j.mimic is None:
                if j.name not in act_index:
                    raise RobotDescriptionError(
                        f"{path}: moving joint {j.name!r} is neither in the spec's actuated_joints nor a mimic joint"
                    )
                return act_index[j.name], 1.0, 0.0
            src, m, c = resolve(joints[j.mimic[0]], depth + 1)
            return src, j.mimic[1] * m, j.mimic[1] * c + j.mimic[2]

        # Anchor of each link: the nearest moving joint at or above it (-1: the root),
        # and the constant transform from that anchor's frame to the link.
        moving: list[JointInfo] = []
        anchor_of_link: dict[str, int] = {model.root: -1}
        const_of_link: dict[str, np.ndarray] = {model.root: np.eye(4)}
        pre: list[np.ndarray] = []  # T_anchor_jointframe of each moving joint
        parent_moving: list[int] = []
        for j in model.joints:  # parents first
            a, C = anchor_of_link[j.parent], const_of_link[j.parent]
            if j.moving:
                moving.append(j)
                pre.append(C @ j.origin)
                parent_moving.append(a)
                anchor_of_link[j.child], const_of_link[j.child] = len(moving) - 1, np.eye(4)
            else:
                anchor_of_link[j.child], const_of_link[j.child] = a, C @ j.origin
        depth = []
        for p in parent_moving:
            depth.append(0 if p < 0 else depth[p] + 1)
        # Sort moving joints by depth so that each level is a contiguous slice.
        order = sorted(range(len(moving)), key=lambda i: (depth[i], i))
        new_pos = {old: new for new, old in enumerate(order)}
        self.moving_names = tuple(moving[i].name for i in order)
        self.moving_parent = [new_pos[parent_moving[i]] if parent_moving[i] >= 0 else -1 for i in order]
        self.moving_pre = np.stack([pre[i] for i in order]) if moving else np.zeros((0, 4, 4))  # (M, 4, 4)
        rules = [resolve(moving[i]) for i in order]
        self.moving_source = tuple(r[0] for r in rules)  # the actuated joint (index into q) that drives each moving joint
        levels = [depth[i] for i in order]
        self.level_slices: list[tuple[int, int]] = []
        for d in sorted(set(levels)):
            idx = [k for k, lv in enumerate(levels) if lv == d]
            self.level_slices.append((idx[0], idx[-1] + 1))
        self.link_names = model.links
        self.link_index = {n: i for i, n in enumerate(model.links)}
        # body 0 = root; body k+1 = child frame of moving joint k (sorted order)
        self.link_body = [0 if anchor_of_link[n] < 0 else new_pos[anchor_of_link[n]] + 1 for n in model.links]
        self.link_const = np.stack([const_of_link[n] for n in model.links])  # (L, 4, 4)
        # Links whose constant is the identity are bodies themselves (no matmul needed);
        # the others ("fixed" links) get one batched matmul. Final link k is row
        # link_gather[k] of cat([bodies (1+M), fixed links (F)]).
        is_fixed = [not np.array_equal(self.link_const[k], np.eye(4)) for k in range(len(model.links))]
        self.fixed_links = [k for k, f in enumerate(is_fixed) if f]
        n_body = 1 + len(moving)
        self.link_gather = [n_body + self.fixed_links.index(k) if f else self.link_body[k] for k, f in enumerate(is_fixed)]
        self._np = {
            "src": np.array([r[0] for r in rules], dtype=np.int64),
            "mult": np.array([r[1] for r in rules]),
            "off": np.array([r[2] for r in rules]),
            "axis": np.stack([moving[i].axis for i in order]) if moving else np.zeros((0, 3)),
        }
        self._build_schedules()
        self._cache: dict[tuple, dict[str, torch.Tensor]] = {}

    def _build_schedules(self) -> None:
        """Constants of the fast FK (numpy, float64); see :meth:`body_poses`."""
        M = len(self.moving_names)
        n = len(self.actuated)
        # theta = q @ theta_map + off: mimic expansion as one matmul
        theta_map = np.zeros((n, M))
        theta_map[self._np["src"], np.arange(M)] = self._np["mult"]
        # T_parentbody_body(theta) = pre @ [[R(theta), 0], [0, 1]] with Rodrigues
        # R = I + sin K + (1 - cos) K^2 = (I + K^2) + sin K - cos K^2, so every local
        # transform is linear in (sin, cos): local = const + [sin | cos] @ coef.
        # Body 0 (the root) is the identity and takes no coefficient.
        const = np.tile(np.eye(4), (1 + M, 1, 1))  # (1+M, 4, 4)
        coef = np.zeros((2 * M, 1 + M, 4, 4))
        for k in range(M):
            a = self._np["axis"][k]
            K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
            H0, HK, HK2 = np.eye(4), np.zeros((4, 4)), np.zeros((4, 4))
            H0[:3, :3] += K @ K
            HK[:3, :3], HK2[:3, :3] = K, K @ K
            pre = self.moving_pre[k]
            const[k + 1] = pre @ H0
            coef[k, k + 1] = pre @ HK
            coef[M + k, k + 1] = -(pre @ HK2)
        self._np["theta_map"] = theta_map
        self._np["local_const"] = const.reshape(-1)
        self._np["local_coef"] = coef.reshape(2 * M, -1)
        # Level by level (large batches: every body is composed once). Bodies are
        # 0 = root, then the moving joints sorted by depth, so a level is a slice.
        parent_body = np.array([0] + [p + 1 for p in self.moving_parent], dtype=np.int64)  # root's parent: itself
        previous = [(-1, 0)] + self.level_slices[:-1]  # each level with the one before it
        self._np["level_parent"] = [  # parent's index within the previous level
            parent_body[1 + s : 1 + e] - (1 + ps) for (ps, _), (s, e) in zip(previous, self.level_slices, strict=True)
        ]
        # Pointer jumping (small batches: ceil(log2(depth + 1)) steps instead of
        # one per level). After step k, body i holds T_{anc}_i with anc its
        # 2^(k+1)-th ancestor (the root, once the chain is exhausted).
        jumps, anc = [], parent_body.copy()
        for _ in range(max(1, math.ceil(math.log2(len(self.level_slices) + 1)))):
            jumps.append(anc.copy())
            anc = anc[anc]
        self._np["jumps"] = jumps
        self._np["link_body"] = np.array(self.link_body, dtype=np.int64)

    @property
    def n_links(self) -> int:
        return len(self.link_names)

    @property
    def n_bodies(self) -> int:
        """1 + the number of moving joints: the root and the child frame of every moving joint."""
        return 1 + len(self.moving_names)

    def _consts(self, device: torch.device, dtype: torch.dtype) -> dict:
        key = (device, dtype)
        c = self._cache.get(key)
        if c is None:
            f = lambda a: torch.as_tensor(a, dtype=dtype, device=device)  # noqa: E731
            i = lambda a: torch.as_tensor(a, dtype=torch.long, device=device)  # noqa: E731
            c = {
                "src": i(self._np["src"]),
                "mult": f(self._np["mult"]),
                "off": f(self._np["off"]),
                "theta_map2": f(np.concatenate([self._np["theta_map"]] * 2, 1)),  # (n, 2M)
                "off2": f(np.concatenate([self._np["off"], self._np["off"] + math.pi / 2])),  # (2M,)
                "local_const": f(self._np["local_const"]),
                "local_coef": f(self._np["local_coef"]),
                "level_parent": [i(p) for p in self._np["level_parent"]],
                "jumps": [i(a) for a in self._np["jumps"]],
                "fixed_body": i([self.link_body[k] for k in self.fixed_links]),
                "fixed_const": f(self.link_const[self.fixed_links]),  # (F, 4, 4)
                "link_gather": i(self.link_gather),
                "link_body": i(self._np["link_body"]),
                "link_const": f(self.link_const),  # (L, 4, 4)
            }
            self._cache[key] = c
        return c

    def joint_angles(self, q: torch.Tensor) -> torch.Tensor:
        """Expand actuated angles ``(..., n)`` to every moving joint ``(..., M)`` (sorted order)."""
        c = self._consts(q.device, q.dtype)
        return q.index_select(-1, c["src"]) * c["mult"] + c["off"]

    def _flat_angles(self, q: torch.Tensor) -> torch.Tensor:
        """Validate ``q (..., n)`` and flatten it to ``(B, n)`` floats."""
        n = len(self.actuated)
        if not isinstance(q, torch.Tensor):
            raise SettingsTypeError(f"{self.model.name}: joint angles must be a torch.Tensor (..., {n}), got {type(q).__name__}")
        if q.ndim == 0 or q.shape[-1] != n:
            raise SettingsError(f"{self.model.name}: expected {n} joint angles in the last dimension, got shape {tuple(q.shape)}")
        if q.is_complex():
            raise SettingsTypeError(f"{self.model.name}: joint angles must be real numbers, got {q.dtype}")
        if not torch.is_floating_point(q):
            q = q.to(torch.get_default_dtype())
        return q.reshape(-1, n)

    def body_poses(self, q: torch.Tensor, compose: str = "levels") -> torch.Tensor:
        """World frames of the root and of every moving joint's child frame.

        Args:
            q: ``(B, n)`` actuated angles [rad].
            compose: ``"levels"`` (:meth:`_compose_by_levels`, the readable form) or
                ``"jumps"`` (:meth:`_compose_by_jumps`, the same product in fewer,
                larger matmuls: faster at small batch).

        Returns:
            ``(B, 1 + M, 4, 4)``; body 0 is the root, body ``k + 1`` the
            moving joint :attr:`moving_names` ``[k]``.
        """
        B = q.shape[0]
        c = self._consts(q.device, q.dtype)
        # [sin theta | cos theta] as one sin of [theta | theta + pi/2]
        sc = torch.sin(torch.addmm(c["off2"], q, c["theta_map2"]))  # (B, 2M)
        local = torch.addmm(c["local_const"], sc, c["local_coef"]).view(B, -1, 4, 4)  # (B, 1+M, 4, 4) T_parent_body
        if compose == "jumps":
            return self._compose_by_jumps(local, c)
        if compose != "levels":
            raise ValueError(f"compose must be one of {COMPOSE_FORMS}, got {compose!r}")
        return self._compose_by_levels(local, c)

    def fast_compose(self, batch: int) -> str:
        """The faster composition at ``batch``: pointer jumping while batch x depth <= :data:`JUMP_MAX_WORK`."""
        return "jumps" if batch * len(self.level_slices) <= JUMP_MAX_WORK else "levels"

    def _compose_by_levels(self, local: torch.Tensor, c: dict) -> torch.Tensor:
        """The reference: ``T_root_body = T_root_parent @ T_parent_body``, one tree level at a time.

        ``local (B, 1+M, 4, 4)`` -> ``(B, 1+M, 4, 4)``.
        """
        root, *moving = local.split([1] + [e - s for s, e in self.level_slices], 1)  # split: one cheap backward
        levels = [root, moving[0]]  # level 0 hangs from the root, whose frame is the identity
        for A_l, parent in zip(moving[1:], c["level_parent"][1:], strict=True):
            levels.append(levels[-1].index_select(1, parent) @ A_l)
        return torch.cat(levels, 1)

    def _compose_by_jumps(self, local: torch.Tensor, c: dict) -> torch.Tensor:
        """The same product by pointer jumping: ``log2(depth)`` rounds of ``T <- T[ancestor] @ T``.

        ``local (B, 1+M, 4, 4)`` -> ``(B, 1+M, 4, 4)``; fewer, larger matmuls than
        :meth:`_compose_by_levels` (cheaper where per-op overhead dominates).
        """
        B = local.shape[0]
        T = local.view(-1, 4, 4)  # (B * (1+M), 4, 4): bmm has less overhead than a 4-d matmul
        for anc in c["jumps"]:
            T = torch.bmm(T.index_select(0, self._batch_index(c, anc, B)), T)
        return T.view(B, -1, 4, 4)

    def _batch_index(self, c: dict, body_index: torch.Tensor, B: int) -> torch.Tensor:
        """``body_index`` applied to each of ``B`` samples of a flat ``(B * (1+M), ...)`` tensor (cached per B)."""
        if B == 1:
            return body_index
        key = ("batch_index", id(body_index), B)
        if key not in c:
            offsets = torch.arange(B, device=body_index.device)[:, None] * self.n_bodies
            c[key] = (body_index + offsets).reshape(-1)
        return c[key]

    def forward(self, q: torch.Tensor) -> torch.Tensor:
        """World poses of every link.

        Args:
            q: ``(..., n)`` actuated joint angles [rad], in :attr:`actuated` order.

        Returns:
            ``(..., L, 4, 4)`` ``T_root_link`` for every link in :attr:`link_names` order.
        """
        q, lead = self._flat_angles(q), q.shape[:-1]  # (B, n); _flat_angles refuses what is no tensor
        c = self._consts(q.device, q.dtype)
        body = self.body_poses(q)  # (B, 1+M, 4, 4)
        # Links with a constant offset from their body: one batched matmul; the
        # others are bodies themselves. Link k is row link_gather[k] of the cat.
        fixed = body.index_select(1, c["fixed_body"]) @ c["fixed_const"]  # (B, F, 4, 4)
        T = torch.cat([body, fixed], 1).index_select(1, c["link_gather"])  # (B, L, 4, 4)
        return T.reshape(*lead, T.shape[1], 4, 4)

    def forward_links(self, q: torch.Tensor, links: torch.Tensor) -> torch.Tensor:
        """World poses of some links only (the rest of the tree's links are not formed).

        Args:
            q: ``(..., n)`` actuated angles [rad].
            links: ``(k,)`` long indices into :attr:`link_names`.

        Returns:
            ``(..., k, 4, 4)`` ``T_root_link``.
        """
        q, lead = self._flat_angles(q), q.shape[:-1]
        c = self._consts(q.device, q.dtype)
        links = links.to(device=q.device)
        body = self.body_poses(q).index_select(1, c["link_body"].index_select(0, links))  # (B, k, 4, 4)
        T = body @ c["link_const"].index_select(0, links)
        return T.reshape(*lead, T.shape[1], 4, 4)

    def point_map(self, links: Sequence[str], vectors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Precompute :meth:`map_points` for homogeneous vectors given in link frames.

        Args:
            links: ``k`` link names.
            vectors: ``(k, 4)`` homogeneous coordinates in each link's frame
                (``w = 1``: a point [m]; ``w = 0``: a direction).

        Returns:
            ``(body (k,) int64, vectors (k, 4) float64 in the body frames)``.
        """
        idx = [self.link_index[n] for n in links]
        vectors = np.asarray(vectors, dtype=np.float64).reshape(len(idx), 4)
        body = np.array([self.link_body[i] for i in idx], dtype=np.int64)
        return body, np.einsum("kij,kj->ki", self.link_const[idx], vectors)

    def map_points(self, q: torch.Tensor, body: torch.Tensor, vectors: torch.Tensor, analytic_gradient: bool = False) -> torch.Tensor:
        """World coordinates of vectors fixed in bodies (see :meth:`point_map`).

        Args:
            q: ``(B, n)`` actuated angles [rad].
            body: ``(k,)`` long body indices.
            vectors: ``(k, 4)`` homogeneous vectors in the body frames.
            analytic_gradient: the faster form: when ``q`` needs a gradient, it is
                computed in closed form (:class:`~nlo_lab.robot.point_gradient.MapPoints`,
                first derivatives only), and the bodies compose as :meth:`fast_compose`
                says. False (the default, the readable form): level-by-level FK that
                autograd differentiates (also for higher derivatives).

        Returns:
            ``(B, k, 3)``: points [m] (``w = 1``) or directions (``w = 0``) in the root frame.
        """
        q = self._flat_angles(q)
        if analytic_gradient and q.requires_grad and torch.is_grad_enabled():
            return MapPoints.apply(q, self, body, vectors)
        compose = self.fast_compose(q.shape[0]) if analytic_gradient else "levels"
        T = self.body_poses(q, compose).index_select(1, body)[..., :3, :]  # (B, k, 3, 4)
        return (T @ vectors[:, :, None])[..., 0]  # B*k products of (3, 4) by (4,)

    def moved_by(self, body: torch.Tensor) -> torch.Tensor:
        """``(M, k)`` 0/1: moving joint ``j`` moves body ``body[i]`` (it is its child frame or an ancestor's)."""
        fast_key = ("moved_by", id(body))  # the same tensor again (the optimisers pass their plan's): no tolist()
        hit = self._cache.get(fast_key)
        if hit is not None and hit[0] is body and hit[1] == body._version:
            return hit[2]
        key = ("moved_by", body.device, tuple(body.tolist()))
        c = self._cache.get(key)
        if c is None:
            parent = [0] + [p + 1 for p in self.moving_parent]  # body -> parent body (root: itself)
            D = np.zeros((len(self.moving_names), len(body)))
            for i, b in enumerate(body.tolist()):
                while b != 0:
                    D[b - 1, i] = 1.0
                    b = parent[b]
            c = self._cache[key] = torch.as_tensor(D, device=body.device)
        self._cache[fast_key] = (body, body._version, c)
        return c

    def joint_axes(self, device: torch.device, dtype: torch.dtype) -> torch.Tensor:
        """``(M, 3)`` unit axis of each moving joint in its own frame."""
        c = self._consts(device, dtype)
        if "axis" not in c:
            c["axis"] = torch.as_tensor(self._np["axis"], dtype=dtype, device=device)
        return c["axis"]

    def numpy_constants(self) -> dict:
        """The float64 constants of :meth:`body_poses` (read-only): ``theta_map (n, M)``, ``off (M,)``,
        ``local_const``, ``local_coef`` (the local transforms, linear in ``[sin | cos]``), ``jumps``
        (the ancestor index of each pointer-jumping round) and ``parent_body (1+M,)``."""
        names = ("theta_map", "off", "local_const", "local_coef", "jumps")
        return {k: self._np[k] for k in names} | {"parent_body": np.array([0] + [p + 1 for p in self.moving_parent])}

    def angle_map(self, device: torch.device, dtype: torch.dtype) -> torch.Tensor:
        """``(n, M)``: the moving joints' angles are ``q @ angle_map + offset`` (mimic joints included)."""
        return self._consts(device, dtype)["theta_map2"][:, : len(self.moving_names)]
