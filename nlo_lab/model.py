"""Encoder and decoder networks of neural latent optimisation.

The paper's graph layer (Zhang et al., Sec. "Graph-based Encoder & Decoder")::

    x_i' = x_i + sum_{j in N(i)} LeakyReLU(W_t [x_i, x_j, e_ji] + b_t)

with one weight set ``(W_t, b_t)`` per node type ``t`` (arm, hand) chosen by
the *receiving* node ``i``. Messages flow along the directed edges,
source (parent) -> target (child); the sum is an ``index_add`` over the edge
list, batched over frames. When the layer changes width the residual ``x_i``
cannot be added as is, so it goes through a per-node-type linear skip
(``P_t x_i``, no bias); at equal width the skip is the identity, as in the paper.
Root nodes have no incoming edge, so their update is the skip alone.

Latent code: ``z`` is ``(B, N_robot, k)``, ``k`` numbers per robot node
(default ``k = 4``: 104 numbers for YuMi with hands, 40 for NAO/Pepper). One
block per joint keeps the decoder a true graph network (each node reads its own
block, its limits and its neighbours) and the code small enough to optimise
in a few milliseconds per iteration.

* :class:`GraphEncoder`: human skeleton graph, per-node widths F -> 16 -> 32 -> 64,
  then one linear map from the flattened node features to ``z``.
* :class:`GraphDecoder`: robot structure graph, per-node input ``z_i ⊕ lower_i ⊕
  upper_i``, widths 32 -> 16 -> 1, ``tanh``, then :func:`remap_to_limits`.
* :class:`MLPEncoder` / :class:`MLPDecoder`: the plain fully connected variants of
  the ablation, same call signatures.
* :class:`RetargetModel`: encoder + decoder + their configuration.
"""

from __future__ import annotations

import math
from typing import Any

import torch
from torch import nn

from nlo_lab import backend
from nlo_lab.errors import SettingsError
from nlo_lab.fused_decoder import DecoderPlan, decode_fused
from nlo_lab.graph import Graph


__all__ = [
    "GraphLayer",
    "GraphEncoder",
    "GraphDecoder",
    "MLPEncoder",
    "MLPDecoder",
    "RetargetModel",
    "remap_to_limits",
    "build_model",
    "MODEL_KINDS",
]

MODEL_KINDS = ("graph", "mlp")
NUM_NODE_TYPES = 2  # NODE_ARM, NODE_HAND
LEAKY_SLOPE = 0.2  # negative slope of the LeakyReLU in the messages


def remap_to_limits(a: torch.Tensor, lower: torch.Tensor, upper: torch.Tensor) -> torch.Tensor:
    """Map ``tanh`` outputs ``a`` in [-1, 1] linearly onto ``[lower, upper]``.

    ``lower + (upper - lower)(a + 1)/2``, then clamped so that float rounding
    can never put an angle one ulp outside its limits (the clamp is inactive
    otherwise and passes gradients through).

    Args:
        a: ``(..., n)`` values; ``tanh`` is applied here, so any real input is fine.
        lower: ``(n,)`` lower limits [rad].
        upper: ``(n,)`` upper limits [rad].

    Returns:
        ``(..., n)`` joint angles inside the limits.
    """
    return _remap(a, (lower + upper) * 0.5, (upper - lower) * 0.5, lower, upper)


def _remap(a: torch.Tensor, mid: torch.Tensor, half: torch.Tensor, lower: torch.Tensor, upper: torch.Tensor) -> torch.Tensor:
    """:func:`remap_to_limits` with ``mid = (lower + upper)/2``, ``half = (upper - lower)/2`` given."""
    return torch.clamp(torch.addcmul(mid, half, torch.tanh(a)), min=lower, max=upper)


def rest_preactivation(rest: torch.Tensor | None, lower: torch.Tensor, upper: torch.Tensor) -> torch.Tensor:
    """``(n,)`` offset before tanh so that a zero network output decodes to ``rest``.

    ``atanh((rest - mid) / half)``, kept within ``atanh(±0.9)`` so that the start
    is never in tanh's flat tail; zeros (the limits' midpoint) without ``rest``.
    """
    if rest is None:
        return torch.zeros_like(lower, dtype=torch.float32)
    u = ((rest.detach().float() - (lower + upper) / 2) / ((upper - lower) / 2).clamp_min(1e-9)).clamp(-0.9, 0.9)
    return torch.atanh(u)


class GraphLayer(nn.Module):
    """One residual message-passing layer with per-node-type weights.

    The weight of type ``t`` is one matrix ``W_t = [W_self | W_nbr | W_edge]`` over
    the concatenation ``[x_i, x_j, e_ji]``; it is applied blockwise (node blocks
    once per node, then gathered per edge), which is the same map as the
    concatenation but avoids materialising ``(B, E, 2C+F)`` and lets static edge
    features be projected once, without the batch dimension.

    Args:
        in_features: node feature width C_in.
        out_features: node feature width C_out.
        edge_features: edge feature width F.
    """

    def __init__(self, in_features: int, out_features: int, edge_features: int):
        super().__init__()
        self.in_features, self.out_features, self.edge_features = in_features, out_features, edge_features
        fan_in = 2 * in_features + edge_features
        bound = 1.0 / math.sqrt(fan_in)  # nn.Linear's default initialisation
        self.weight = nn.Parameter(torch.empty(NUM_NODE_TYPES, out_features, fan_in).uniform_(-bound, bound))
        self.bias = nn.Parameter(torch.empty(NUM_NODE_TYPES, out_features).uniform_(-bound, bound))
        # Linear skip when the width changes (the paper's residual needs equal widths).
        if in_features == out_features:
            self.skip = None
        else:
            b = 1.0 / math.sqrt(in_features)
            self.skip = nn.Parameter(torch.empty(NUM_NODE_TYPES, out_features, in_features).uniform_(-b, b))

    def forward(
        self,
        x: torch.Tensor,
        edge_index: torch.Tensor,
        edge_attr: torch.Tensor,
        node_type: torch.Tensor,
    ) -> torch.Tensor:
        """Update node features.

        Args:
            x: ``(B, N, C_in)`` node features.
            edge_index: ``(2, E)`` source j -> target i.
            edge_attr: ``(E, F)`` static or ``(B, E, F)`` per-sample edge features.
            node_type: ``(N,)`` :data:`NODE_ARM` / :data:`NODE_HAND`.

        Returns:
            ``(B, N, C_out)``.
        """
        B, N, C = x.shape
        O, K = self.out_features, NUM_NODE_TYPES
        src, dst = edge_index[0], edge_index[1]
        t_edge = node_type[dst]  # weights of the receiving node's type
        w_self, w_nbr, w_edge = self.weight.split([C, C, self.edge_features], dim=-1)  # (K, O, .)
        blocks = [w_self, w_nbr] + ([] if self.skip is None else [self.skip])
        # Every node through every block and type at once: (B, N, nb*K*O).
        y = x @ torch.cat(blocks, dim=0).reshape(-1, C).T
        nb = len(blocks)
        y = y.reshape(B, N * nb * K, O)
        def col(node, block, t):  # row of y for (node, block, type)
            return (node * nb + block) * K + t

        msg = y.index_select(1, col(dst, 0, t_edge)) + y.index_select(1, col(src, 1, t_edge))  # (B, E, O)
        if edge_attr.ndim == 2:  # static: project once, (E, O)
            msg = msg + (torch.einsum("ef,eof->eo", edge_attr, w_edge[t_edge]) + self.bias[t_edge])
        else:  # per sample: (B, E, O)
            msg = msg + torch.einsum("bef,eof->beo", edge_attr, w_edge[t_edge]) + self.bias[t_edge]
        msg = nn.functional.leaky_relu(msg, LEAKY_SLOPE)
        agg = x.new_zeros(B, N, O).index_add(1, dst, msg)  # (B, N, O): sum over incoming edges
        if self.skip is None:
            res = x
        else:
            nodes = torch.arange(N, device=x.device)
            res = y.index_select(1, col(nodes, 2, node_type))
        return res + agg


    def node_major_weights(
        self, edge_index: torch.Tensor, edge_attr: torch.Tensor, node_type: torch.Tensor, fixed: torch.Tensor | None = None
    ) -> dict[str, torch.Tensor]:
        """This layer's weights gathered per edge and per node, for :meth:`forward_node_major`.

        Static edge features, the bias and the contribution of constant input
        features (``fixed``: the last ``D`` input columns, the same for every
        sample) are folded into one bias per edge and per node: at inference
        they cost nothing per call.

        Args:
            edge_index: ``(2, E)`` source -> target.
            edge_attr: ``(E, F)`` static edge features.
            node_type: ``(N,)``.
            fixed: ``(N, D)`` constant last input columns, or None.

        Returns:
            ``src, dst (E,)``, ``self (E, C', O)``, ``nbr (E, C', O)``, ``bias (E, 1, O)``,
            ``skip (N, C', O)`` or None (identity), ``skip_bias (N, 1, O)`` or None;
            ``C' = C_in - D``.
        """
        src, dst = edge_index[0], edge_index[1]
        C, D = self.in_features, 0 if fixed is None else fixed.shape[-1]
        t_edge = node_type[dst]  # weights of the receiving node's type
        w_self, w_nbr, w_edge = self.weight.index_select(0, t_edge).split([C, C, self.edge_features], dim=-1)  # (E, O, .)
        bias = torch.einsum("ef,eof->eo", edge_attr.to(w_edge.dtype), w_edge) + self.bias.index_select(0, t_edge)  # (E, O)
        skip = None if self.skip is None else self.skip.index_select(0, node_type)  # (N, O, C)
        skip_bias = None
        if fixed is not None:
            fixed = fixed.to(w_self.dtype)
            bias = bias + torch.einsum("ed,eod->eo", fixed[dst], w_self[..., C - D :]) + torch.einsum("ed,eod->eo", fixed[src], w_nbr[..., C - D :])
            if skip is None:  # identity on the variable columns only
                skip = torch.eye(self.out_features, C, dtype=w_self.dtype, device=w_self.device).expand(len(node_type), -1, -1)
            skip_bias = torch.einsum("nd,nod->no", fixed, skip[..., C - D :])[:, None]
            skip = skip[..., : C - D]
        return {
            "src": src,
            "dst": dst,
            "self": w_self[..., : C - D].mT,
            "nbr": w_nbr[..., : C - D].mT,
            "bias": bias[:, None],
            "skip": None if skip is None else skip.mT,
            "skip_bias": skip_bias,
        }

    @staticmethod
    def forward_node_major(x: torch.Tensor, w: dict[str, torch.Tensor]) -> torch.Tensor:
        """The layer on node-major features: ``x (N, B, C')`` -> ``(N, B, O)``.

        Same map as :meth:`forward` (with ``w`` from :meth:`node_major_weights`)
        in a handful of batched matmuls over edges and nodes, which at small
        batch is what matters (per-op overhead).
        """
        msg = torch.baddbmm(w["bias"], x.index_select(0, w["dst"]), w["self"])  # (E, B, O)
        msg = torch.baddbmm(msg, x.index_select(0, w["src"]), w["nbr"])
        msg = nn.functional.leaky_relu(msg, LEAKY_SLOPE)
        if w["skip"] is None:
            res = x
        elif w["skip_bias"] is None:
            res = torch.bmm(x, w["skip"])
        else:
            res = torch.baddbmm(w["skip_bias"], x, w["skip"])
        return res.index_add(0, w["dst"], msg)  # + sum over incoming edges


class _GraphBuffers(nn.Module):
    """Holds a graph's tensors as buffers so that ``.to()`` moves them."""

    def __init__(self, graph: Graph):
        super().__init__()
        self.node_names = tuple(graph.node_names)
        self.register_buffer("edge_index", graph.edge_index.long().clone(), persistent=False)
        self.register_buffer("edge_attr", graph.edge_attr.float().clone(), persistent=False)
        self.register_buffer("node_type", graph.node_type.long().clone(), persistent=False)


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
    """

    def __init__(
        self,
        human_graph: Graph,
        in_features: int,
        edge_features: int,
        n_robot_nodes: int,
        latent_per_node: int = 4,
        widths: tuple[int, ...] = (16, 32, 64),
    ):
        super().__init__()
        self.graph = _GraphBuffers(human_graph)
        self.n_robot_nodes, self.latent_per_node = n_robot_nodes, latent_per_node
        dims = (in_features, *widths)
        self.layers = nn.ModuleList(GraphLayer(a, b, edge_features) for a, b in zip(dims[:-1], dims[1:]))
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


class GraphDecoder(nn.Module):
    """Latent ``z (B, N_r, k)`` -> joint angles ``q (B, n)`` inside the limits.

    Args:
        robot_graph: ``robot.graph`` (nodes = actuated joints, edge_attr (E, 6)).
        lower: ``(n,)`` lower limits [rad], node order = joint order.
        upper: ``(n,)`` upper limits [rad].
        latent_per_node: ``k``.
        widths: per-node widths (paper: 32, 16, 1; the last must be 1).
        rest: ``(n,)`` angles [rad] decoded when the layers output 0 (the
            robot's neutral pose); None: the limits' midpoint, as the paper's
            remap. Training starts there, and the arm configuration it starts
            in is the one it keeps (see :func:`rest_preactivation`).
    """

    def __init__(
        self,
        robot_graph: Graph,
        lower: torch.Tensor,
        upper: torch.Tensor,
        latent_per_node: int = 4,
        widths: tuple[int, ...] = (32, 16, 1),
        rest: torch.Tensor | None = None,
    ):
        super().__init__()
        if widths[-1] != 1:
            raise SettingsError(f"the decoder's last width must be 1 (one angle per joint), got {widths}")
        n = robot_graph.num_nodes
        if lower.shape != (n,) or upper.shape != (n,):
            raise SettingsError(f"limits must be ({n},) like the robot graph, got {tuple(lower.shape)}/{tuple(upper.shape)}")
        self.graph = _GraphBuffers(robot_graph)
        self.latent_per_node = latent_per_node
        self.register_buffer("lower", lower.detach().float().clone(), persistent=False)
        self.register_buffer("upper", upper.detach().float().clone(), persistent=False)
        self.register_buffer("rest_pre", rest_preactivation(rest, self.lower, self.upper))  # (n,), saved in checkpoints
        edge_f = robot_graph.edge_attr.shape[-1]
        dims = (latent_per_node + 2, *widths)
        self.layers = nn.ModuleList(GraphLayer(a, b, edge_f) for a, b in zip(dims[:-1], dims[1:]))

    @property
    def latent_shape(self) -> tuple[int, int]:
        """``(N_r, k)``: the shape of one sample's latent."""
        return (self.graph.node_type.shape[0], self.latent_per_node)

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        """``z (B, N_r, k)`` -> ``q (B, n)`` [rad]."""
        w = self._weights()
        plan = w.get("plan")  # frozen weights on the CPU: numpy with a hand-written backward
        if plan is not None and backend.numpy_decoder(z.shape[0]) and z.device.type == "cpu" and z.dtype == w["mid"].dtype:
            return decode_fused(z, plan)
        return _remap(self._preactivation(z, w), w["mid"], w["half"], w["lower"], w["upper"])

    def preactivation(self, z: torch.Tensor) -> torch.Tensor:
        """``z (B, N_r, k)`` -> ``a (B, n)``, the values before tanh (``q = remap(a)``).

        Useful to see saturation: a joint whose ``a`` sits in tanh's flat tail is
        pinned at its limit and passes no gradient, in training or to the latent.
        """
        return self._preactivation(z, self._weights())

    def remap(self, a: torch.Tensor) -> torch.Tensor:
        """``a (B, n)`` -> ``q (B, n)`` inside the limits (tanh, then the linear remap)."""
        return remap_to_limits(a, self.lower, self.upper)

    def _preactivation(self, z: torch.Tensor, w: dict) -> torch.Tensor:
        x = z.transpose(0, 1)  # (N_r, B, k): node-major, see GraphLayer.forward_node_major
        for layer, wl in zip(self.layers, w["layers"]):
            x = layer.forward_node_major(x, wl)
        return x[..., 0].T + w["rest_pre"]

    def _weights(self) -> dict:
        """Per-layer node-major weights with the limits folded in.

        Cached while no parameter needs a gradient (inference, latent
        optimisation); the key holds every parameter's version counter, so an
        in-place update (an optimiser step, ``load_state_dict``) rebuilds it.
        """
        params = self.__dict__.get("_param_list")
        if params is None:  # the module tree is fixed after __init__; walking it costs ~40 us per call
            params = self.__dict__["_param_list"] = list(self.parameters())
        frozen = not any(p.requires_grad for p in params)
        key = tuple((p.data_ptr(), p._version, p.dtype, p.device) for p in params) + tuple(
            (b.data_ptr(), b._version) for b in (self.lower, self.rest_pre)
        )
        if frozen and getattr(self, "_weights_cache", (None,))[0] == key:
            return self._weights_cache[1]
        g = self.graph
        fixed = torch.stack([self.lower, self.upper], dim=-1)  # (N_r, 2): constant input columns
        w = {
            "layers": [],
            "mid": (self.lower + self.upper) * 0.5,
            "half": (self.upper - self.lower) * 0.5,
            "lower": self.lower,
            "upper": self.upper,
            "rest_pre": self.rest_pre,
        }
        for i, layer in enumerate(self.layers):
            w["layers"].append(layer.node_major_weights(g.edge_index, g.edge_attr, g.node_type, fixed if i == 0 else None))
        if frozen:
            if self.lower.device.type == "cpu":
                w["plan"] = DecoderPlan(w, len(g.node_type), LEAKY_SLOPE)
            self._weights_cache = (key, w)
        return w


def _mlp(dims: tuple[int, ...]) -> nn.Sequential:
    mods: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(dims[:-1], dims[1:])):
        mods.append(nn.Linear(a, b))
        if i < len(dims) - 2:
            mods.append(nn.LeakyReLU(LEAKY_SLOPE))
    return nn.Sequential(*mods)


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
    ):
        super().__init__()
        del edge_features  # part of the common signature only
        self.n_robot_nodes, self.latent_per_node = n_robot_nodes, latent_per_node
        self.net = _mlp((human_graph.num_nodes * in_features, *widths, n_robot_nodes * latent_per_node))

    def forward(self, node_x: torch.Tensor, edge_x: torch.Tensor | None = None) -> torch.Tensor:
        """``node_x (B, N_h, F)`` -> ``z (B, N_r, k)``."""
        return self.net(node_x.flatten(1)).view(-1, self.n_robot_nodes, self.latent_per_node)


class MLPDecoder(nn.Module):
    """Plain fully connected decoder (ablation): ``z ⊕ lower ⊕ upper`` -> tanh -> remap."""

    def __init__(
        self,
        robot_graph: Graph,
        lower: torch.Tensor,
        upper: torch.Tensor,
        latent_per_node: int = 4,
        widths: tuple[int, ...] = (128, 64),
        rest: torch.Tensor | None = None,
    ):
        super().__init__()
        n = robot_graph.num_nodes
        self.n_nodes, self.latent_per_node = n, latent_per_node
        self.register_buffer("lower", lower.detach().float().clone(), persistent=False)
        self.register_buffer("upper", upper.detach().float().clone(), persistent=False)
        self.register_buffer("rest_pre", rest_preactivation(rest, self.lower, self.upper))
        self.net = _mlp((n * (latent_per_node + 2), *widths, n))

    @property
    def latent_shape(self) -> tuple[int, int]:
        """``(N_r, k)``."""
        return (self.n_nodes, self.latent_per_node)

    def forward(self, z: torch.Tensor) -> torch.Tensor:
        """``z (B, N_r, k)`` -> ``q (B, n)`` [rad]."""
        return self.remap(self.preactivation(z))

    def preactivation(self, z: torch.Tensor) -> torch.Tensor:
        """``z (B, N_r, k)`` -> ``a (B, n)`` before tanh (see :meth:`GraphDecoder.preactivation`)."""
        B = z.shape[0]
        lim = torch.stack([self.lower, self.upper], dim=-1).expand(B, -1, -1)
        return self.net(torch.cat([z, lim], dim=-1).flatten(1)) + self.rest_pre

    def remap(self, a: torch.Tensor) -> torch.Tensor:
        """``a (B, n)`` -> ``q (B, n)`` inside the limits."""
        return remap_to_limits(a, self.lower, self.upper)


class RetargetModel(nn.Module):
    """Encoder ``f_phi`` and decoder ``f_psi`` for one robot, with their configuration.

    Attributes:
        encoder: human features -> ``z (B, N_r, k)``.
        decoder: ``z`` -> ``q (B, n)``.
        robot_name: the robot the decoder was built for.
        config: hyperparameters needed to rebuild the model (:func:`build_model`).
    """

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

    def encode(self, node_x: torch.Tensor, edge_x: torch.Tensor | None = None) -> torch.Tensor:
        """Human features ``(B, N_h, F)`` (+ ``(B, E_h, 3)``) -> ``z (B, N_r, k)``."""
        return self.encoder(node_x, edge_x)

    def decode(self, z: torch.Tensor) -> torch.Tensor:
        """``z (B, N_r, k)`` -> ``q (B, n)`` inside the joint limits."""
        return self.decoder(z)

    def forward(self, node_x: torch.Tensor, edge_x: torch.Tensor | None = None) -> tuple[torch.Tensor, torch.Tensor]:
        """Encoder then decoder; returns ``(q, z)``."""
        z = self.encode(node_x, edge_x)
        return self.decode(z), z


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

    Raises:
        SettingsError: unknown kind or a non-positive latent size.
    """
    if kind not in MODEL_KINDS:
        raise SettingsError(f"unknown model kind {kind!r}; expected one of {MODEL_KINDS}")
    if int(latent_per_node) < 1:
        raise SettingsError(f"latent_per_node must be >= 1, got {latent_per_node}")
    enc_cls, dec_cls = (GraphEncoder, GraphDecoder) if kind == "graph" else (MLPEncoder, MLPDecoder)
    n_r = robot_graph.num_nodes
    encoder = enc_cls(human_graph, in_features, edge_features, n_r, latent_per_node)
    decoder = dec_cls(robot_graph, lower, upper, latent_per_node, rest=rest)
    config = {
        "kind": kind,
        "latent_per_node": int(latent_per_node),
        "in_features": int(in_features),
        "edge_features": int(edge_features),
        "human_nodes": int(human_graph.num_nodes),
        "robot_nodes": int(n_r),
    }
    return RetargetModel(encoder, decoder, robot_name, config)
