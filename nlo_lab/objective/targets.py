"""The demonstration as the objective compares it: torch tensors, masks, arm lengths.

Masks: a masked target contributes exactly nothing to the objective. Its value is
replaced by a finite placeholder (0, or the identity for rotations) *and* its term
is selected away (``torch.where``), so neither the loss nor its gradient ever sees
NaN or depends on the masked value.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
import torch

from nlo_lab.errors import DemonstrationError
from nlo_lab.human.demonstration import SIDES, Demonstration

__all__ = ["Targets", "targets_from_demonstration"]


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
        hand_length: ``(T, 2)`` demonstrator's hand length: the mean wrist -> knuckle (index..pinky
            finger base) distance, median over the sequence [m] (the hand terms' unit).
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
    hand_length: torch.Tensor
    fps: float | None = None

    def __len__(self) -> int:
        return int(self.shoulder.shape[0])

    @property
    def dtype(self) -> torch.dtype:
        return self.shoulder.dtype

    def _map(self, fn) -> Targets:
        out = {f.name: fn(f.name, getattr(self, f.name)) for f in fields(self) if f.name != "fps"}
        return Targets(**out, fps=self.fps)

    def to(self, device=None, dtype=None) -> Targets:
        """A copy on ``device``; ``dtype`` applies to the float tensors only."""
        return self._map(lambda n, t: t.to(device=device, dtype=dtype if t.is_floating_point() else None))

    def index(self, idx) -> Targets:
        """Frames ``idx`` (a slice, index tensor or boolean mask) as new targets."""
        return self._map(lambda n, t: t[idx])

    @staticmethod
    def cat(items: list[Targets]) -> Targets:
        """Concatenate along frames."""
        if not items:
            raise DemonstrationError("no targets to concatenate")
        rates = {t.fps for t in items}
        out = {"fps": rates.pop() if len(rates) == 1 else None}
        for f in fields(Targets):
            if f.name == "fps":
                continue
            out[f.name] = torch.cat([getattr(t, f.name) for t in items], dim=0)
        return Targets(**out)


def _sequence_lengths(demo: Demonstration, side: str) -> tuple[float, float]:
    """Median (upper + fore, fore) of one arm [m]; a never fully observed arm gets 1."""
    try:
        upper, fore = demo.arm_lengths(side)
    except DemonstrationError:
        return 1.0, 1.0  # every ee/elbow target of this arm is masked anyway
    return upper + fore, fore


def _hand_length(demo: Demonstration, s: int) -> float:
    """Median over the frames of the mean wrist -> knuckle distance of the four fingers [m]; 1 if never seen."""
    seen = demo.finger_mask[:, s, 1:].all(-1) & demo.arm_mask[:, s, 2]
    if not seen.any():
        return 1.0  # every hand target of this side is masked anyway
    knuckles = demo.finger_positions[seen, s, 1:, 0]  # (n, 4, 3)
    return float(np.median(np.linalg.norm(knuckles - demo.arm_positions[seen, s, 2][:, None], axis=-1).mean(-1)))


def targets_from_demonstration(demo: Demonstration, dtype: torch.dtype = torch.float32, device=None) -> Targets:
    """Build :class:`Targets` from a :class:`Demonstration` (numpy, NaN where masked).

    Arm and hand lengths are per sequence (median), broadcast per frame. The encoder reads the
    same frames differently: :func:`nlo_lab.model.encoder_input`.
    """
    T = len(demo)

    def tensor(a: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(np.nan_to_num(np.asarray(a, dtype=np.float64)), dtype=dtype, device=device)

    def mask(a: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(np.asarray(a, dtype=bool), device=device)

    rot = np.where(demo.wrist_mask[..., None, None], np.nan_to_num(demo.wrist_rotations), np.eye(3))
    lengths = np.array([_sequence_lengths(demo, s) for s in SIDES])  # (2, 2)
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
        hand_length=tensor(np.broadcast_to([_hand_length(demo, s) for s in range(2)], (T, 2))),
        fps=float(demo.fps),
    )
