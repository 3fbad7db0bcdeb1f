"""The retargeting network of one robot: encoder ``f_phi`` + decoder ``f_psi`` and their configuration."""

from __future__ import annotations

from typing import Any

import torch
from torch import nn

from nlo_lab.errors import SettingsError
from nlo_lab.graph import Graph
from nlo_lab.model.decoder import GraphDecoder, MLPDecoder
from nlo_lab.model.encoder import GraphEncoder, MLPEncoder
from nlo_lab.model.layers import ACTIVATIONS, DEFAULT_ACTIVATION

__all__ = ["RetargetModel", "build_model", "MODEL_KINDS"]

MODEL_KINDS = ("graph", "mlp")


class RetargetModel(nn.Module):
    """Encoder ``f_phi`` and decoder ``f_psi`` for one robot, with their configuration.

    Attributes:
        encoder: human features -> ``z (B, N_r, k)``.
        decoder: ``z`` -> ``q (B, n)``.
        robot_name: the robot the decoder was built for.
        config: hyperparameters needed to rebuild the model (:func:`build_model`).
    """

    latent_mean: torch.Tensor  # a buffer (typed here: nn.Module's __getattr__ says Tensor | Module)
    latent_std: torch.Tensor

    def __init__(self, encoder: nn.Module, decoder: nn.Module, robot_name: str, config: dict[str, Any]):
        super().__init__()
        self.encoder, self.decoder = encoder, decoder
        self.robot_name = robot_name
        self.config = dict(config)
        # Mean and spread of the encoder's latents over the training frames (the
        # ``train-stats`` initialisation); N(0, 1) until training fills them in.
        shape = decoder.latent_shape
        self.register_buffer("latent_mean", torch.zeros(shape))
        self.register_buffer("latent_std", torch.ones(shape))

    @property
    def latent_shape(self) -> tuple[int, int]:
        """``(N_r, k)``: the latent of one frame."""
        return self.decoder.latent_shape

    @property
    def has_encoder(self) -> bool:
        """False for a model trained as an auto-decoder (``config["training"] == "autodecoder"``):
        its encoder was never trained, so it cannot start latent optimisation."""
        return self.config.get("training", "encoder") != "autodecoder"

    def encode(self, node_x: torch.Tensor, edge_x: torch.Tensor | None = None) -> torch.Tensor:
        """Human features ``(B, N_h, F)`` (+ ``(B, E_h, 3)``) -> ``z (B, N_r, k)``."""
        return self.encoder(node_x, edge_x)

    def decode(self, z: torch.Tensor, form: str = "paper") -> torch.Tensor:
        """``z (B, N_r, k)`` -> ``q (B, n)`` inside the joint limits (``form``: see :meth:`GraphDecoder.forward`)."""
        return self.decoder(z, form=form)

    def forward(self, node_x: torch.Tensor, edge_x: torch.Tensor | None = None, form: str = "paper") -> tuple[torch.Tensor, torch.Tensor]:
        """Encoder then decoder (``form``: the decoder's, :meth:`GraphDecoder.forward`); returns ``(q, z)``."""
        z = self.encode(node_x, edge_x)
        return self.decode(z, form), z


def build_model(
    robot_name: str,
    robot_graph: Graph,
    lower: torch.Tensor,
    upper: torch.Tensor,
    human_graph: Graph,
    in_features: int,
    edge_features: int = 3,
    kind: str = "graph",
    latent_per_node: int = 4,
    rest: torch.Tensor | None = None,
    activation: str = DEFAULT_ACTIVATION,
) -> RetargetModel:
    """Build an untrained :class:`RetargetModel`.

    Args:
        robot_name: recorded in the model (and in checkpoints).
        robot_graph: ``robot.graph``.
        lower, upper: ``(n,)`` joint limits [rad].
        human_graph: ``nlo_lab.human.skeleton_graph()``.
        in_features: F of ``node_features(demo)``.
        edge_features: width of ``edge_features(demo)``.
        kind: ``"graph"`` (the paper) or ``"mlp"`` (the ablation).
        latent_per_node: ``k`` of ``z (B, N_r, k)``.
        rest: ``(n,)`` the decoder's rest angles (``robot.neutral_q``); None: midpoint.
        activation: the message activation of encoder and decoder, one of
            :data:`~nlo_lab.model.layers.ACTIVATIONS` (the paper's Table II); default LeakyReLU, the paper's.

    Raises:
        SettingsError: unknown kind or activation, or a non-positive latent size.
    """
    if kind not in MODEL_KINDS:
        raise SettingsError(f"unknown model kind {kind!r}; expected one of {MODEL_KINDS}")
    if activation not in ACTIVATIONS:
        raise SettingsError(f"unknown activation {activation!r}; expected one of {', '.join(ACTIVATIONS)}")
    if int(latent_per_node) < 1:
        raise SettingsError(f"latent_per_node must be >= 1, got {latent_per_node}")
    enc_cls, dec_cls = (GraphEncoder, GraphDecoder) if kind == "graph" else (MLPEncoder, MLPDecoder)
    n_r = robot_graph.num_nodes
    encoder = enc_cls(human_graph, in_features, edge_features, n_r, latent_per_node, activation=activation)
    decoder = dec_cls(robot_graph, lower, upper, latent_per_node, rest=rest, activation=activation)
    config = {
        "kind": kind,
        "latent_per_node": int(latent_per_node),
        "in_features": int(in_features),
        "edge_features": int(edge_features),
        "human_nodes": int(human_graph.num_nodes),
        "robot_nodes": int(n_r),
        "activation": activation,
    }
    return RetargetModel(encoder, decoder, robot_name, config)
