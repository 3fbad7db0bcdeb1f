"""The retargeting objective L(D, K(q)) of the paper, term by term.

Every term is returned per sample, shape ``(B,)``, summed over arms / fingers /
collision pairs as in the paper's equations (Sec. "Problem Statement"):

* ``ee``: end effector, ``sum_side ||p/l - p̂/l̂||²`` with ``p`` the wrist position
  relative to the shoulder, ``l`` the robot's zero-pose upper + fore arm length,
  ``l̂`` the demonstrator's upper + fore arm length (median over the sequence).
  The robot's shoulder is a point fixed to its body: the shoulder link's
  position at the reference pose (``robot.shoulder_position``), where the metric
  places the human shoulder too. YuMi's shoulder link (link 2) sits off joint
  1's axis and swings by up to 6 cm; measuring from it, the optimum put the
  wrist that far from where the metric scores it.
* ``ori``: ``sum_side ||R_wrist R_align - R̂||_F²``; ``R_align`` is the spec's
  per-arm ``wrist_alignment`` (robot wrist link -> human wrist convention).
* ``elbow``: ``sum_side ||(w - e)/l_fore - (ŵ - ê)/l̂_fore||²``.
* ``finger``: ``sum_{side,finger} ||u - û||²`` with ``u`` the unit base -> tip
  direction (normalised by the finger's own length); 0 for robots without fingers.
* ``collision``: over the spec's capsule pairs closer than their margin
  ``d_min``. Default form ``"hinge"``: ``sum ((d_min - d)/d_min)²`` for
  ``d < d_min``. The paper's ``sum exp(-d²) [d < d_min]`` (form ``"paper"``) jumps
  at ``d_min``, has almost no gradient near contact (``-2d e^{-d²}`` -> 0) and,
  with the surface distance of ``robot.capsule_distances`` (< 0 inside), pushes
  penetrating capsules *deeper*; the squared hinge is zero above ``d_min``,
  continuous with its gradient, and always pushes the capsules apart.

The latent regulariser ``||z||²/σ²`` (:func:`latent_loss`) is added where ``z``
lives (optimisation, training).

Temporal coherence (not in the paper, which has "no mechanism to ensure smoothness"):
``smooth`` (:func:`smoothness_loss`) couples consecutive frames of a sequence,
``sum_j ((q_t,j - q_t-1,j) fps / v_max,j)²``: each joint's speed in units of its
published velocity limit, squared. It removes jitter and branch flips (a jump between
two arm configurations costs the square of its speed), and it weighs a joint by how
slow the robot is there, so the motion the robot cannot follow is what it trades
against tracking. It is added by the optimisers, which see the whole sequence; it is
not one of the per-frame :data:`TERMS`. Masks: a masked target contributes exactly
nothing: its value is replaced by a finite placeholder *and* its term is
selected away with ``torch.where``, so neither the loss nor its gradient ever
sees NaN or depends on the masked value.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields
from typing import Optional

import numpy as np
import torch

from nlo_lab import backend
from nlo_lab.robot.collision import segment_distance_ends
from nlo_lab.errors import DemonstrationError, SettingsError
from nlo_lab.fused_objective import _UNIT_EPS, PointTerms, point_terms
from nlo_lab.human.demonstration import FINGERS, SIDES, Demonstration
from nlo_lab.human.skeleton import edge_features, node_features
from nlo_lab.robot.point_gradient import left_matmul

__all__ = [
    "LossWeights",
    "Targets",
    "TERMS",
    "COLLISION_FORMS",
    "targets_from_demonstration",
    "objective",
    "Objective",
    "end_effector_loss",
    "orientation_loss",
    "elbow_loss",
    "finger_loss",
    "collision_loss",
    "latent_loss",
    "smoothness_loss",
    "smoothness_scale",
    "step_cost",
    "robot_points",
    "near_pair_distances",
]

TERMS = ("ee", "ori", "elbow", "finger", "collision")
COLLISION_FORMS = ("hinge", "paper")
# A joint faster than this [rad/s] is smoothed as if its limit were this: NAO's wrist
# (24.6 rad/s) could otherwise jump 0.85 rad between two frames at little cost, though
# a jump is jitter whatever the motor (measured: docs/RESULTS.md, "Robot-ready motion").
SMOOTH_SPEED_CAP = math.pi
SMOOTH_MAX_STEP = 0.35  # [rad] a joint step beyond this between two frames costs steeply ...
SMOOTH_STEP_WIDTH = 0.02  # [rad] ... (one more width: one more unit, squared)
CULL_SLACK = 1e-4  # [m] a capsule pair is skipped only when its lower bound clears the margin by this much


# ---------------------------------------------------------------------- weights
@dataclass(frozen=True)
class LossWeights:
    """Weights of the objective's terms (defaults: the paper's).

    Attributes:
        ee: end-effector position term.
        ori: wrist orientation term.
        elbow: elbow -> wrist direction term.
        finger: finger base -> tip direction term.
        collision: self-collision term.
        latent: weight of ``||z||²`` (``1/σ²``, σ = 1 in the paper).
        smooth: weight of the joint-speed term over consecutive frames
            (:func:`smoothness_loss`; not in the paper; 0 = frames independent).
    """

    ee: float = 1000.0
    ori: float = 100.0
    elbow: float = 100.0
    finger: float = 100.0
    collision: float = 1000.0
    latent: float = 1.0
    smooth: float = 10.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            try:
                number = float(value)
            except (TypeError, ValueError):
                raise SettingsError(f"loss weight {f.name} must be a number, got {value!r}") from None
            if not math.isfinite(number) or number < 0:
                raise SettingsError(f"loss weight {f.name} must be finite and >= 0, got {value!r}")
            object.__setattr__(self, f.name, number)

    @classmethod
    def from_string(cls, text: str) -> "LossWeights":
        """Parse ``"ee=1000,ori=100"``; unnamed weights keep their defaults.

        Raises:
            SettingsError: naming the bad key or value.
        """
        names = {f.name for f in fields(cls)}
        values: dict[str, float] = {}
        for item in (part.strip() for part in text.split(",")):
            if not item:
                continue
            key, sep, raw = item.partition("=")
            key = key.strip()
            if not sep:
                raise SettingsError(f"weight {item!r} is not KEY=VALUE (keys: {', '.join(sorted(names))})")
            if key not in names:
                raise SettingsError(f"unknown weight {key!r}; expected one of {', '.join(sorted(names))}")
            if key in values:
                raise SettingsError(f"weight {key!r} given twice")
            try:
                values[key] = float(raw)
            except ValueError:
                raise SettingsError(f"weight {key}={raw.strip()!r} is not a number") from None
        return cls(**values)

    def as_dict(self) -> dict[str, float]:
        """``{name: weight}``."""
        return dataclasses.asdict(self)


# ---------------------------------------------------------------------- targets
@dataclass(frozen=True)
class Targets:
    """Torch version of a demonstration, ready for the objective (T frames).

    Masked values are replaced by finite placeholders (0, or the identity for
    rotations); the masks say which ones count. Positions in the body frame [m].

    Attributes:
        shoulder, elbow, wrist: ``(T, 2, 3)`` per side (left, right).
        arm_mask: ``(T, 2, 3)`` bool: shoulder, elbow, wrist observed.
        wrist_rotation: ``(T, 2, 3, 3)`` ``R_body_wrist``.
        wrist_mask: ``(T, 2)`` bool.
        finger_base, finger_tip: ``(T, 2, 5, 3)``, fingers thumb..pinky.
        finger_mask: ``(T, 2, 5)`` bool.
        arm_length: ``(T, 2)`` demonstrator's upper + fore arm length [m].
        fore_length: ``(T, 2)`` demonstrator's forearm length [m].
        node_features: ``(T, N_h, F)`` encoder input, or None.
        edge_features: ``(T, E_h, 3)`` encoder edge input, or None.
        fps: frame rate of the sequence (the smoothness term's time step), or None.
    """

    shoulder: torch.Tensor
    elbow: torch.Tensor
    wrist: torch.Tensor
    arm_mask: torch.Tensor
    wrist_rotation: torch.Tensor
    wrist_mask: torch.Tensor
    finger_base: torch.Tensor
    finger_tip: torch.Tensor
    finger_mask: torch.Tensor
    arm_length: torch.Tensor
    fore_length: torch.Tensor
    node_features: Optional[torch.Tensor] = None
    edge_features: Optional[torch.Tensor] = None
    fps: Optional[float] = None

    def __len__(self) -> int:
        return int(self.shoulder.shape[0])

    @property
    def dtype(self) -> torch.dtype:
        return self.shoulder.dtype

    def _map(self, fn) -> "Targets":
        out = {f.name: None if getattr(self, f.name) is None else fn(f.name, getattr(self, f.name)) for f in fields(self) if f.name != "fps"}
        return Targets(**out, fps=self.fps)

    def to(self, device=None, dtype=None) -> "Targets":
        """A copy on ``device``; ``dtype`` applies to the float tensors only."""
        return self._map(lambda n, t: t.to(device=device, dtype=dtype if t.is_floating_point() else None))

    def index(self, idx) -> "Targets":
        """Frames ``idx`` (a slice, index tensor or boolean mask) as new targets."""
        return self._map(lambda n, t: t[idx])

    @staticmethod
    def cat(items: "list[Targets]") -> "Targets":
        """Concatenate along frames (encoder features kept only if all have them)."""
        if not items:
            raise DemonstrationError("no targets to concatenate")
        rates = {t.fps for t in items}
        out = {"fps": rates.pop() if len(rates) == 1 else None}
        for f in fields(Targets):
            if f.name == "fps":
                continue
            values = [getattr(t, f.name) for t in items]
            out[f.name] = None if any(v is None for v in values) else torch.cat(values, dim=0)
        return Targets(**out)


def _sequence_lengths(demo: Demonstration, side: str) -> tuple[float, float]:
    """Median (upper + fore, fore) of one arm [m]; a never fully observed arm gets 1."""
    try:
        upper, fore = demo.arm_lengths(side)
    except DemonstrationError:
        return 1.0, 1.0  # every ee/elbow target of this arm is masked anyway
    return upper + fore, fore


def targets_from_demonstration(demo: Demonstration, dtype: torch.dtype = torch.float32, device=None) -> Targets:
    """Build :class:`Targets` from a :class:`Demonstration` (numpy, NaN where masked).

    Arm lengths are per sequence (median), broadcast per frame. Encoder inputs
    come from ``nlo_lab.human.node_features`` / ``edge_features`` (NaN -> 0).
    """
    T = len(demo)

    def tensor(a: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(np.nan_to_num(np.asarray(a, dtype=np.float64)), dtype=dtype, device=device)

    def mask(a: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(np.asarray(a, dtype=bool), device=device)

    rot = np.where(demo.wrist_mask[..., None, None], np.nan_to_num(demo.wrist_rotations), np.eye(3))
    lengths = np.array([_sequence_lengths(demo, s) for s in SIDES])  # (2, 2)
    node_x, edge_x = tensor(node_features(demo)), tensor(edge_features(demo))  # the encoder's inputs
    return Targets(
        shoulder=tensor(demo.arm_positions[:, :, 0]),
        elbow=tensor(demo.arm_positions[:, :, 1]),
        wrist=tensor(demo.arm_positions[:, :, 2]),
        arm_mask=mask(demo.arm_mask),
        wrist_rotation=tensor(rot),
        wrist_mask=mask(demo.wrist_mask),
        finger_base=tensor(demo.finger_positions[:, :, :, 0]),
        finger_tip=tensor(demo.finger_positions[:, :, :, 1]),
        finger_mask=mask(demo.finger_mask),
        arm_length=tensor(np.broadcast_to(lengths[:, 0], (T, 2))),
        fore_length=tensor(np.broadcast_to(lengths[:, 1], (T, 2))),
        node_features=node_x,
        edge_features=edge_x,
        fps=float(demo.fps),
    )


# ---------------------------------------------------------------------- robot side
class _RobotConstants:
    """Per-robot tensors the objective needs every call (computed once)."""

    def __init__(self, robot, dtype: torch.dtype, device):
        self.robot = robot
        arms = [robot.arm(s) for s in SIDES]
        self.elbow = [a.elbow for a in arms]
        self.wrist = [a.wrist for a in arms]
        self.align = torch.stack([torch.as_tensor(a.wrist_alignment) for a in arms]).to(device=device, dtype=dtype)  # (2,3,3)
        # the shoulder: fixed to the body, at the shoulder link's reference-pose position
        self.shoulder_ref = torch.stack([robot.shoulder_position(s_) for s_ in SIDES]).to(device=device, dtype=dtype)  # (2, 3)
        lengths = [robot.zero_pose_lengths(s) for s in SIDES]
        self.arm_length = torch.tensor([float(u) + float(f) for u, f in lengths], dtype=dtype, device=device)  # (2,)
        self.fore_length = torch.tensor([float(f) for _, f in lengths], dtype=dtype, device=device)  # (2,)
        # Fingers the robot has: (side index, finger index, base link, tip link).
        self.fingers = []
        if getattr(robot, "has_fingers", False):
            for s, arm in enumerate(arms):
                for f, name in enumerate(FINGERS):
                    if arm.fingers and name in arm.fingers:
                        base, tip = arm.fingers[name]
                        self.fingers.append((s, f, base, tip))
        self.finger_side = torch.tensor([s for s, *_ in self.fingers], dtype=torch.long, device=device)
        self.finger_index = torch.tensor([f for _, f, *_ in self.fingers], dtype=torch.long, device=device)
        self.margins = torch.as_tensor(robot.collision_margins).to(device=device, dtype=dtype)  # (P,)
        self._build_point_plan(robot, arms, lengths, dtype, device)

    def _build_point_plan(self, robot, arms, lengths, dtype, device) -> None:
        """Everything the objective reads from FK as constant vectors in link frames.

        Points (``w = 1``): shoulder, elbow, wrist per side, finger base and tip,
        capsule end points; directions (``w = 0``): the three columns of each
        wrist's aligned rotation. ``rows @ points`` then gives the residual rows
        of the fast objective: ee (2), ori columns (6), elbow (2), finger (K).
        """
        links, vecs = [], []

        def add(link: str, xyz, w: float) -> int:
            links.append(link)
            vecs.append([*xyz, w])
            return len(links) - 1

        role = {(r, s): add(getattr(arm, r), (0.0, 0.0, 0.0), 1.0) for s, arm in enumerate(arms) for r in ("elbow", "wrist")}
        for s in range(2):  # a point on the root body: the fixed shoulder
            role["shoulder", s] = add(robot.tree.model.root, self.shoulder_ref[s].double().cpu().numpy(), 1.0)
        cols = [[add(arm.wrist, np.asarray(arm.wrist_alignment, dtype=np.float64)[:, j], 0.0) for j in range(3)] for arm in arms]
        fingers = [(add(base, (0.0, 0.0, 0.0), 1.0), add(tip, (0.0, 0.0, 0.0), 1.0)) for *_, base, tip in self.fingers]
        caps = [[add(cap.link, end, 1.0) for end in (cap.p0, cap.p1)] for cap in robot.spec.capsules]
        rows = []  # (V, K): each residual row as a signed, scaled combination of points
        K = len(links)

        def row(entries) -> None:
            r = np.zeros(K)
            for k, v in entries:
                r[k] += v
            rows.append(r)

        for s in range(2):
            l_arm = float(lengths[s][0]) + float(lengths[s][1])
            row([(role["wrist", s], 1.0 / l_arm), (role["shoulder", s], -1.0 / l_arm)])
        for s in range(2):
            for j in range(3):
                row([(cols[s][j], 1.0)])
        for s in range(2):
            l_fore = float(lengths[s][1])
            row([(role["wrist", s], 1.0 / l_fore), (role["elbow", s], -1.0 / l_fore)])
        for base, tip in fingers:
            row([(tip, 1.0), (base, -1.0)])
        body, vectors = robot.tree.point_map(links, np.array(vecs))
        f = lambda a: torch.as_tensor(a, dtype=dtype, device=device)  # noqa: E731
        self.point_body = torch.as_tensor(body, dtype=torch.long, device=device)  # (K,)
        self.point_vectors = f(vectors)  # (K, 4) in body frames
        self.rows = f(np.array(rows))  # (V, K)
        n_rows = [2, 6, 2, len(fingers)]  # ee, ori, elbow, finger
        self.finger_row = torch.as_tensor(np.repeat([False, False, False, True], n_rows)[:, None], device=device)  # (V, 1)
        self.row_term = f(np.repeat(np.eye(4), n_rows, axis=0))  # (V, 4) row -> term
        pair_caps = np.array([[robot.spec.capsules.index(robot.spec.capsule(n)) for n in pr] for pr in robot.spec.collision_pairs], dtype=np.int64)
        cap_pts = np.array(caps, dtype=np.int64).reshape(-1, 2)
        self.pair_points = torch.as_tensor(cap_pts[pair_caps].reshape(-1), dtype=torch.long, device=device)  # (4P,) a0 a1 b0 b1
        radii = np.array([c.radius for c in robot.spec.capsules])
        self.pair_radii = f(radii[pair_caps].sum(-1).reshape(-1))  # (P,) [m]


_CONSTANTS: dict[tuple[int, torch.dtype, str], _RobotConstants] = {}


def _constants(robot, dtype: torch.dtype, device) -> _RobotConstants:
    key = (id(robot), dtype, str(device))
    c = _CONSTANTS.get(key)
    if c is None or c.robot is not robot:
        c = _CONSTANTS[key] = _RobotConstants(robot, dtype, device)
    return c


def _pos(poses: dict, link: str) -> torch.Tensor:
    return poses[link][..., :3, 3]


def robot_points(robot, poses: dict) -> dict[str, torch.Tensor]:
    """The robot's role points from FK poses.

    Returns:
        ``shoulder`` (the fixed reference point), ``elbow``, ``wrist`` ``(B, 2, 3)``, ``wrist_rotation``
        ``(B, 2, 3, 3)`` (aligned to the human wrist convention), and
        ``finger_base``, ``finger_tip`` ``(B, K, 3)`` for the robot's K fingers
        (K = 0 without hands).
    """
    some = next(iter(poses.values()))
    c = _constants(robot, some.dtype, some.device)
    B = some.shape[0]
    out = {
        "shoulder": c.shoulder_ref.expand(B, 2, 3),  # fixed to the body (module docstring)
        "elbow": torch.stack([_pos(poses, l) for l in c.elbow], dim=1),
        "wrist": torch.stack([_pos(poses, l) for l in c.wrist], dim=1),
        "wrist_rotation": torch.stack([poses[l][..., :3, :3] for l in c.wrist], dim=1) @ c.align,
    }
    if c.fingers:
        out["finger_base"] = torch.stack([_pos(poses, b) for *_, b, _ in c.fingers], dim=1)
        out["finger_tip"] = torch.stack([_pos(poses, t) for *_, t in c.fingers], dim=1)
    else:
        out["finger_base"] = out["finger_tip"] = some.new_zeros(B, 0, 3)
    return out


# ---------------------------------------------------------------------- terms
def _masked_sum(values: torch.Tensor, mask: torch.Tensor) -> torch.Tensor:
    """Sum over dims after the first of ``values`` where ``mask``, exactly 0 elsewhere."""
    return torch.where(mask, values, torch.zeros_like(values)).flatten(1).sum(1)


def end_effector_loss(shoulder, wrist, arm_length, t_shoulder, t_wrist, t_arm_length, mask) -> torch.Tensor:
    """``sum_side ||(w - s)/l - (ŵ - ŝ)/l̂||²``.

    Args:
        shoulder, wrist: ``(B, 2, 3)`` robot [m]; arm_length ``(2,)`` or ``(B, 2)``.
        t_shoulder, t_wrist: ``(B, 2, 3)`` human [m]; t_arm_length ``(B, 2)``.
        mask: ``(B, 2)`` both shoulder and wrist observed.

    Returns:
        ``(B,)``.
    """
    p = (wrist - shoulder) / arm_length[..., None]
    p_hat = (t_wrist - t_shoulder) / t_arm_length[..., None]
    return _masked_sum((p - p_hat).pow(2).sum(-1), mask)


def orientation_loss(rotation, t_rotation, mask) -> torch.Tensor:
    """``sum_side ||R - R̂||_F²``; rotation ``(B, 2, 3, 3)`` already aligned, mask ``(B, 2)``."""
    return _masked_sum((rotation - t_rotation).pow(2).sum((-1, -2)), mask)


def elbow_loss(elbow, wrist, fore_length, t_elbow, t_wrist, t_fore_length, mask) -> torch.Tensor:
    """``sum_side ||(w - e)/l_fore - (ŵ - ê)/l̂_fore||²``; shapes as :func:`end_effector_loss`."""
    v = (wrist - elbow) / fore_length[..., None]
    v_hat = (t_wrist - t_elbow) / t_fore_length[..., None]
    return _masked_sum((v - v_hat).pow(2).sum(-1), mask)




def _unit(v: torch.Tensor, eps: float = _UNIT_EPS) -> torch.Tensor:
    return v / v.pow(2).sum(-1, keepdim=True).add(eps).sqrt()


def finger_loss(base, tip, t_base, t_tip, mask) -> torch.Tensor:
    """``sum_finger ||u - û||²`` of unit base -> tip directions.

    Args:
        base, tip: ``(B, K, 3)`` robot; t_base, t_tip: ``(B, K, 3)`` the matching
            human fingers; mask ``(B, K)``. K = 0 gives zeros.
    """
    if base.shape[1] == 0:
        return base.new_zeros(base.shape[0])
    return _masked_sum((_unit(tip - base) - _unit(t_tip - t_base)).pow(2).sum(-1), mask)


def collision_loss(distances: torch.Tensor, margins: torch.Tensor, form: str = "hinge") -> torch.Tensor:
    """Self-collision penalty over capsule pairs closer than their margin.

    Args:
        distances: ``(B, P)`` surface distances [m] (< 0 = penetration).
        margins: ``(P,)`` d_min per pair [m].
        form: ``"hinge"`` (default; ``((d_min - d)/d_min)²``) or ``"paper"`` (``exp(-d²)``).

    Returns:
        ``(B,)``, exactly 0 when every pair is at least ``d_min`` apart.
    """
    if form not in COLLISION_FORMS:
        raise SettingsError(f"unknown collision form {form!r}; expected one of {COLLISION_FORMS}")
    if distances.shape[-1] == 0:
        return distances.new_zeros(distances.shape[0])
    if form == "paper":
        return _masked_sum(torch.exp(-distances.pow(2)), distances < margins)
    # clamp: exactly 0 (and no gradient) at and above d_min, fewer ops than a masked sum
    return ((margins - distances) / margins).clamp_min(0.0).pow(2).sum(-1)


def latent_loss(z: torch.Tensor, sigma: float = 1.0) -> torch.Tensor:
    """``||z||²/σ²`` per sample: ``z (B, ...)`` -> ``(B,)``."""
    return z.pow(2).flatten(1).sum(1) / (sigma * sigma)


def smoothness_scale(velocity_limits: torch.Tensor) -> torch.Tensor:
    """``(n,)`` the speed unit of each joint in :func:`smoothness_loss`: its velocity limit,
    at most :data:`SMOOTH_SPEED_CAP` (unlimited joints count at the cap)."""
    return velocity_limits.clamp(max=SMOOTH_SPEED_CAP)


def smoothness_loss(q: torch.Tensor, fps: float, velocity_limits: torch.Tensor) -> torch.Tensor:
    """Joint speed between consecutive frames in units of each joint's velocity limit, squared.

    Args:
        q: ``(T, n)`` joint angles of consecutive frames [rad].
        fps: frame rate [1/s].
        velocity_limits: ``(n,)`` [rad/s] (see :func:`smoothness_scale`).

    Returns:
        ``(T,)``: frame t holds ``sum_j ((q_t,j - q_t-1,j) fps / v_j)²``, frame 0 holds 0.
    """
    if q.shape[0] == 0:
        return q.new_zeros(0)
    return torch.cat([q.new_zeros(1), step_cost(q[1:] - q[:-1], fps, velocity_limits)])


def step_cost(step: torch.Tensor, fps: float, velocity_limits: torch.Tensor) -> torch.Tensor:
    """The smoothness cost of joint changes ``step (..., n)`` [rad] between two frames -> ``(...)``.

    ``sum_j (step_j fps / s_j)²`` with ``s`` = :func:`smoothness_scale`, plus
    ``sum_j ((|step_j| - MAX_STEP) / STEP_WIDTH)²`` over the joints that move more than
    :data:`SMOOTH_MAX_STEP` in one frame: a fast joint (NAO's wrist, 24.6 rad/s) may follow
    a fast human rotation within its speed limit, but not by jumping half a radian
    between two samples (the robot's controller would see a step, not a motion).
    """
    speed = step * (fps / smoothness_scale(velocity_limits).to(step.dtype))
    jump = (step.abs() - SMOOTH_MAX_STEP).clamp_min(0.0) / SMOOTH_STEP_WIDTH
    return speed.pow(2).sum(-1) + jump.pow(2).sum(-1)


def near_pair_distances(ends: torch.Tensor, radii: torch.Tensor, margins: torch.Tensor) -> torch.Tensor:
    """Capsule surface distances ``(B, P)``, exact where a pair may be closer than its margin.

    A cheap lower bound first: no point of a segment is farther from its midpoint than
    half its length, so ``dist >= |m_a - m_b| - h_a - h_b``. Where that bound minus the
    radii is at least the margin (plus :data:`CULL_SLACK` for rounding), the pair is
    certainly clear: it gets the bound itself, without gradient, which every
    :func:`collision_loss` form maps to exactly 0 loss and 0 gradient. Only the other
    pairs go through :func:`nlo_lab.robot.collision.segment_distance_ends` (on the test split
    with YuMi about one pair in seven at batch 170).

    Args:
        ends: ``(B, P, 4, 3)`` end points a0, a1, b0, b1 [m].
        radii: ``(P,)`` summed radii; margins: ``(P,)`` d_min [m].
    """
    with torch.no_grad():
        a0, a1, b0, b1 = ends.unbind(-2)
        half = (a1 - a0).norm(dim=-1) + (b1 - b0).norm(dim=-1)  # (B, P): twice h_a + h_b
        bound = ((a0 + a1 - b0 - b1).norm(dim=-1) - half) / 2 - radii  # (B, P) <= surface distance
        near = (bound < margins + CULL_SLACK).nonzero(as_tuple=True)
    if near[0].numel() == 0:
        return bound
    exact = segment_distance_ends(ends[near]) - radii.expand_as(bound)[near]
    return bound.index_put(near, exact)  # differentiable in the exact values only


# ---------------------------------------------------------------------- objective
class Objective:
    """The objective of :func:`objective` for one robot, one set of targets and weights.

    Everything that does not depend on ``q`` is computed once here (the human
    side of every term, the masks, the robot's constant point plan), so that a
    call is one FK and a few batched tensor ops: the latent optimisation calls
    it every iteration, where per-op overhead dominates at small batch.

    A call maps every needed point and direction to the world at once
    (:meth:`nlo_lab.robot.kinematics.KinematicTree.map_points`), forms the residual
    rows of ee, ori (wrist rotation columns), elbow and finger with one matmul,
    and the capsule pair distances from the same points.

    Args:
        robot: a loaded ``nlo_lab.robot.Robot``.
        targets: :class:`Targets` (T frames); its dtype and device are used.
        weights: :class:`LossWeights`.
        collision_form: see :func:`collision_loss`.
        fused: compute the terms from the FK points in numpy with a hand-written
            backward (:mod:`nlo_lab.fused_objective`); ``None`` = on the CPU for
            as many frames as :func:`nlo_lab.backend.numpy_objective` allows; ``False`` = torch ops (the reference).
        cull: with torch ops, measure exactly only the capsule pairs that may be
            closer than their margin (:func:`near_pair_distances`); the others add
            exactly 0 to the loss and its gradient either way. False = every pair;
            None = unless :func:`nlo_lab.backend.reference`.
    """

    def __init__(
        self,
        robot,
        targets: Targets,
        weights: LossWeights | None = None,
        collision_form: str = "hinge",
        fused: bool | None = None,
        cull: bool | None = None,
    ):
        if collision_form not in COLLISION_FORMS:
            raise SettingsError(f"unknown collision form {collision_form!r}; expected one of {COLLISION_FORMS}")
        weights = weights or LossWeights()
        self.robot, self.n_frames, self.collision_form = robot, len(targets), collision_form
        self.cull = backend.cull_far_pairs() if cull is None else cull
        t = targets
        c = self._c = _constants(robot, t.dtype, t.shoulder.device)
        with torch.no_grad():
            am = t.arm_mask
            parts = [
                (t.wrist - t.shoulder) / t.arm_length[..., None],  # (T, 2, 3) ee
                t.wrist_rotation.mT.reshape(-1, 6, 3),  # (T, 6, 3) ori: columns of R̂, side-major
                (t.wrist - t.elbow) / t.fore_length[..., None],  # (T, 2, 3) elbow
            ]
            masks = [am[..., 0] & am[..., 2], t.wrist_mask.repeat_interleave(3, dim=1), am[..., 1] & am[..., 2]]
            if c.fingers:
                sel = (slice(None), c.finger_side, c.finger_index)
                parts.append(_unit(t.finger_tip[sel] - t.finger_base[sel]))  # (T, K, 3)
                masks.append(t.finger_mask[sel])
            self.goal = torch.cat(parts, 1)  # (T, V, 3)
            self.mask = torch.cat(masks, 1)  # (T, V) bool
            self.weights = torch.tensor([getattr(weights, n) for n in TERMS], dtype=t.dtype, device=t.shoulder.device)  # (5,)
        if fused is None:
            fused = t.shoulder.device.type == "cpu" and backend.numpy_objective(len(targets))
        self._plan = None
        if fused:
            self._plan = PointTerms(
                c.rows.numpy(), c.finger_row[:, 0].numpy(), c.row_term.argmax(1).numpy(), self.goal.numpy(), self.mask.numpy(),
                c.pair_points.numpy(), c.pair_radii.numpy(), c.margins.numpy(), collision_form,
            )

    def __call__(self, q: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """``q (B, n)`` -> ``total (B,)`` and the unweighted terms ``(B, 5)`` in :data:`TERMS` order."""
        if q.shape[0] != self.n_frames:
            raise SettingsError(f"q has {q.shape[0]} frames but the targets have {self.n_frames}")
        c = self._c
        pts = self.robot.tree.map_points(q, c.point_body, c.point_vectors)  # (B, K, 3)
        if self._plan is not None:
            terms = point_terms(pts, self._plan)  # (B, 5)
            return terms @ self.weights, terms
        v = left_matmul(c.rows, pts)  # (B, V, 3) residual rows before the goal
        # finger rows become unit directions (as _unit), the others stay
        v = v * torch.where(c.finger_row, (v.pow(2).sum(-1, keepdim=True) + _UNIT_EPS).rsqrt(), 1.0)
        sq = torch.where(self.mask, (v - self.goal).pow(2).sum(-1), 0.0)  # (B, V)
        ends = pts.index_select(1, c.pair_points).view(q.shape[0], -1, 4, 3)  # (B, P, 4, 3)
        if self.cull:
            d = near_pair_distances(ends, c.pair_radii, c.margins)
        else:
            d = segment_distance_ends(ends) - c.pair_radii  # (B, P) capsule surface distances [m]
        terms = torch.cat([sq @ c.row_term, collision_loss(d, c.margins, self.collision_form)[:, None]], 1)  # (B, 5)
        return terms @ self.weights, terms


def objective(
    robot,
    q: torch.Tensor,
    targets: Targets,
    weights: LossWeights | None = None,
    *,
    poses: dict | None = None,
    collision_form: str = "hinge",
) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """The weighted objective ``L(D, K(q))`` per sample (without the latent term).

    Args:
        robot: a loaded ``nlo_lab.robot.Robot``.
        q: ``(B, n)`` joint angles [rad].
        targets: :class:`Targets` with ``B`` frames.
        weights: :class:`LossWeights` (defaults of the paper).
        poses: FK of ``q`` if already computed.
        collision_form: see :func:`collision_loss`.

    Returns:
        ``total (B,)`` and the unweighted terms ``{"ee","ori","elbow","finger","collision"}``, each ``(B,)``.
    """
    weights = weights or LossWeights()
    if len(targets) != q.shape[0]:
        raise SettingsError(f"q has {q.shape[0]} frames but the targets have {len(targets)}")
    if poses is None:
        total, terms = Objective(robot, targets, weights, collision_form)(q)
        return total, dict(zip(TERMS, terms.unbind(1)))
    # Given poses (every link): the term functions one by one, the reference for Objective.
    c = _constants(robot, q.dtype, q.device)
    pts = robot_points(robot, poses)
    t = targets
    am = t.arm_mask
    terms = {
        "ee": end_effector_loss(pts["shoulder"], pts["wrist"], c.arm_length, t.shoulder, t.wrist, t.arm_length, am[..., 0] & am[..., 2]),
        "ori": orientation_loss(pts["wrist_rotation"], t.wrist_rotation, t.wrist_mask),
        "elbow": elbow_loss(pts["elbow"], pts["wrist"], c.fore_length, t.elbow, t.wrist, t.fore_length, am[..., 1] & am[..., 2]),
    }
    if c.fingers:
        sel = (slice(None), c.finger_side, c.finger_index)
        terms["finger"] = finger_loss(pts["finger_base"], pts["finger_tip"], t.finger_base[sel], t.finger_tip[sel], t.finger_mask[sel])
    else:
        terms["finger"] = q.new_zeros(q.shape[0])
    terms["collision"] = collision_loss(robot.capsule_distances(poses), c.margins, collision_form)
    total = sum(getattr(weights, name) * terms[name] for name in TERMS)
    return total, terms
