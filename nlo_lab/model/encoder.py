"""Encoders ``f_phi``: the human's features of a frame -> the latent code ``z``.

Latent code: ``z`` is ``(B, N_robot, k)``, ``k`` numbers per robot node
(default ``k = 4``: 104 numbers for YuMi with hands, 40 for NAO/Pepper). One
block per joint keeps the decoder a true graph network (each node reads its own
block, its limits and its neighbours) and the code small enough to optimise
in a few milliseconds per iteration.

* :class:`GraphEncoder`: human skeleton graph, per-node widths F -> 16 -> 32 -> 64
  (:class:`~nlo_lab.model.layers.GraphLayer`), then one linear map from the
  flattened node features to ``z``.
* :class:`MLPEncoder`: the plain fully connected variant of the ablation, same call signature.
"""

from __future__ import annotations

import torch
from torch import nn

from nlo_lab.graph import Graph
from nlo_lab.model.layers import DEFAULT_ACTIVATION, GraphBuffers, GraphLayer, mlp

__all__ = ["GraphEncoder", "MLPEncoder"]


class GraphEncoder(nn.Module):
    """Human skeleton graph -> latent ``z`` ``(B, N_robot, k)``.

    Args:
        human_graph: the skeleton graph (only structure and node types are used;
            edge features come per sample from the caller).
        in_features: node feature width F of ``node_features(demo)``.
        edge_features: human edge feature width (3: bone offsets).
        n_robot_nodes: nodes of the robot graph (actuated joints).
        latent_per_node: ``k``.
        widths: per-node hidden widths (paper: 16, 32, 64).
        activation: the layers' message activation (:data:`~nlo_lab.model.layers.ACTIVATIONS`; paper: LeakyReLU).
    """

    def __init__(
        self,
        human_graph: Graph,
        in_features: int,
        edge_features: int,
        n_robot_nodes: int,
        latent_per_node: int = 4,
        widths: tuple[int, ...] = (16, 32, 64),
        activation: str = DEFAULT_ACTIVATION,
    ):
        super().__init__()
        self.graph = GraphBuffers(human_graph)
        self.n_robot_nodes, self.latent_per_node = n_robot_nodes, latent_per_node
        self.activation = activation
        dims = (in_features, *widths)
        self.layers = nn.ModuleList(GraphLayer(a, b, edge_features, activation) for a, b in zip(dims[:-1], dims[1:], strict=True))
        self.to_latent = nn.Linear(human_graph.num_nodes * widths[-1], n_robot_nodes * latent_per_node)

    def forward(self, node_x: torch.Tensor, edge_x: torch.Tensor | None = None) -> torch.Tensor:
        """``node_x (B, N_h, F)``, ``edge_x (B, E_h, 3)`` or None (the graph's static offsets) -> ``z (B, N_r, k)``."""
        g = self.graph
        e = g.edge_attr.to(node_x.dtype) if edge_x is None else edge_x
        x = node_x
        for layer in self.layers:
            x = layer(x, g.edge_index, e, g.node_type)
        z = self.to_latent(x.flatten(1))
        return z.view(-1, self.n_robot_nodes, self.latent_per_node)


class MLPEncoder(nn.Module):
    """Plain fully connected encoder (ablation): flattened node features -> ``z``.

    Same call signature as :class:`GraphEncoder`; edge features are ignored.
    """

    def __init__(
        self,
        human_graph: Graph,
        in_features: int,
        edge_features: int,
        n_robot_nodes: int,
        latent_per_node: int = 4,
        widths: tuple[int, ...] = (256, 256),
        activation: str = DEFAULT_ACTIVATION,
    ):
        super().__init__()
        del edge_features  # part of the common signature only
        self.n_robot_nodes, self.latent_per_node = n_robot_nodes, latent_per_node
        self.activation = activation
        self.net = mlp((human_graph.num_nodes * in_features, *widths, n_robot_nodes * latent_per_node), activation)

    def forward(self, node_x: torch.Tensor, edge_x: torch.Tensor | None = None) -> torch.Tensor:
        """``node_x (B, N_h, F)`` -> ``z (B, N_r, k)``."""
        return self.net(node_x.flatten(1)).view(-1, self.n_robot_nodes, self.latent_per_node)
