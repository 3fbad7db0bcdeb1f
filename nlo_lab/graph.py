"""Graph container shared by the human skeleton graph and the robot structure graph.

The graph layer of the paper (``GraphLayer``) lives in :mod:`nlo_lab.model`;
this module only holds the structure: directed edges parent -> child, edge
features and node types.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

__all__ = ["Graph", "NODE_ARM", "NODE_HAND"]

NODE_ARM = 0  # node type of arm joints (and the torso / shoulders of the human)
NODE_HAND = 1  # node type of hand / finger joints


@dataclass(frozen=True)
class Graph:
    """A directed graph with edge features and typed nodes.

    Attributes:
        node_names: one name per node, in node order.
        edge_index: ``(2, E)`` long tensor; row 0 the source (parent), row 1 the
            target (child). Messages flow along the edges, source -> target.
        edge_attr: ``(E, F)`` static edge features, or ``(B, E, F)`` per sample
            (the human graph's bone offsets change from frame to frame).
        node_type: ``(N,)`` long tensor of :data:`NODE_ARM` / :data:`NODE_HAND`.
    """

    node_names: tuple[str, ...]
    edge_index: torch.Tensor
    edge_attr: torch.Tensor
    node_type: torch.Tensor

    def __post_init__(self) -> None:
        n = len(self.node_names)
        if self.edge_index.ndim != 2 or self.edge_index.shape[0] != 2:
            raise ValueError(f"edge_index must be (2, E), got {tuple(self.edge_index.shape)}")
        if self.edge_index.numel() and (self.edge_index.min() < 0 or self.edge_index.max() >= n):
            raise ValueError("edge_index refers to a node that does not exist")
        if self.edge_attr.shape[-2] != self.edge_index.shape[1]:
            raise ValueError("edge_attr must have one row per edge")
        if self.node_type.shape != (n,):
            raise ValueError(f"node_type must be ({n},), got {tuple(self.node_type.shape)}")

    @property
    def num_nodes(self) -> int:
        return len(self.node_names)

    @property
    def num_edges(self) -> int:
        return int(self.edge_index.shape[1])

    def to(self, device=None, dtype=None) -> Graph:
        """A copy on ``device``; ``dtype`` applies to the float edge features only."""
        return Graph(
            self.node_names,
            self.edge_index.to(device=device),
            self.edge_attr.to(device=device, dtype=dtype),
            self.node_type.to(device=device),
        )
