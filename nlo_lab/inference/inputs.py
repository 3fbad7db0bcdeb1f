"""What the latent optimisation and the training read of a demonstration's frames.

:class:`RetargetInputs` pairs what the objective compares (:class:`~nlo_lab.objective.Targets`)
with what the encoder reads (:class:`~nlo_lab.model.EncoderInput`), the same T frames each.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from nlo_lab.human import Demonstration
from nlo_lab.model import EncoderInput, encoder_input
from nlo_lab.objective import Targets, targets_from_demonstration

__all__ = ["RetargetInputs"]


@dataclass(frozen=True)
class RetargetInputs:
    """Demonstration frames as the latent optimisation and the training read them: what
    the objective compares (:class:`~nlo_lab.objective.Targets`) and what the encoder
    reads (:class:`~nlo_lab.model.EncoderInput`), the same T frames each."""

    targets: Targets
    encoder: EncoderInput

    def __len__(self) -> int:
        return len(self.targets)

    def index(self, idx) -> RetargetInputs:
        """Frames ``idx`` (a slice, index tensor or boolean mask)."""
        return RetargetInputs(self.targets.index(idx), self.encoder.index(idx))

    def to(self, device=None, dtype=None) -> RetargetInputs:
        """A copy on ``device``; ``dtype`` applies to the float tensors only."""
        return RetargetInputs(self.targets.to(device=device, dtype=dtype), self.encoder.to(device=device, dtype=dtype))

    @staticmethod
    def cat(items: list[RetargetInputs]) -> RetargetInputs:
        """Concatenate along frames."""
        return RetargetInputs(Targets.cat([x.targets for x in items]), EncoderInput.cat([x.encoder for x in items]))

    @staticmethod
    def from_demonstration(demo: Demonstration, dtype: torch.dtype = torch.float32, device=None) -> RetargetInputs:
        """Targets in ``dtype`` on ``device``; the encoder's input in float32 (the models' dtype) on ``device``."""
        return RetargetInputs(targets_from_demonstration(demo, dtype=dtype, device=device), encoder_input(demo, device=device))
