"""What the encoder reads of a demonstration: per-frame node and edge features of the skeleton graph.

The objective compares the robot with the demonstration (:class:`nlo_lab.objective.Targets`);
the encoder reads a different view of the same frames, the skeleton graph's features
(:func:`nlo_lab.human.node_features`, :func:`nlo_lab.human.edge_features`). They travel
separately: the loss does not carry the network's input.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from nlo_lab.errors import DemonstrationError
from nlo_lab.human.demonstration import Demonstration
from nlo_lab.human.skeleton import edge_features, node_features

__all__ = ["EncoderInput", "encoder_input"]


@dataclass(frozen=True)
class EncoderInput:
    """The encoder's input for T frames.

    Attributes:
        node_features: ``(T, N_h, F)`` (``F = 13``; masked points are 0 with validity 0).
        edge_features: ``(T, E_h, 3)`` bone offsets.
    """

    node_features: torch.Tensor
    edge_features: torch.Tensor

    def __len__(self) -> int:
        return int(self.node_features.shape[0])

    def to(self, device=None, dtype=None) -> EncoderInput:
        """A copy on ``device`` in ``dtype``."""
        return EncoderInput(self.node_features.to(device=device, dtype=dtype), self.edge_features.to(device=device, dtype=dtype))

    def index(self, idx) -> EncoderInput:
        """Frames ``idx`` (a slice, index tensor or boolean mask)."""
        return EncoderInput(self.node_features[idx], self.edge_features[idx])

    @staticmethod
    def cat(items: list[EncoderInput]) -> EncoderInput:
        """Concatenate along frames."""
        if not items:
            raise DemonstrationError("no encoder inputs to concatenate")
        return EncoderInput(torch.cat([x.node_features for x in items]), torch.cat([x.edge_features for x in items]))


def encoder_input(demo: Demonstration, dtype: torch.dtype = torch.float32, device=None) -> EncoderInput:
    """The encoder's input for every frame of ``demo`` (NaN -> 0)."""

    def tensor(a: np.ndarray) -> torch.Tensor:
        return torch.as_tensor(np.nan_to_num(np.asarray(a, dtype=np.float64)), dtype=dtype, device=device)

    return EncoderInput(tensor(node_features(demo)), tensor(edge_features(demo)))
