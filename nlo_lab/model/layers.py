"""The paper's graph layer, the limit remap, and the pieces both networks share.

The graph layer (Zhang et al., Sec. "Graph-based Encoder & Decoder")::

    x_i' = x_i + sum_{j in N(i)} LeakyReLU(W_t [x_i, x_j, e_ji] + b_t)

with one weight set ``(W_t, b_t)`` per node type ``t`` (arm, hand) chosen by
the *receiving* node ``i``. The message activation ``g`` is the paper's LeakyReLU by
default; :data:`ACTIVATIONS` holds the alternatives of the paper's Table II
(Sigmoid, Tanh, ReLU), chosen per model (``build_model(activation=...)``). Messages flow along the directed edges,
source (parent) -> target (child). When the layer changes width the residual
``x_i`` cannot be added as is, so it goes through a per-node-type linear skip
(``P_t x_i``, no bias); at equal width the skip is the identity, as in the paper.
Root nodes have no incoming edge, so their update is the skip alone.

:meth:`GraphLayer.forward` is that equation, written as it reads. The frozen
decoder evaluates the same map faster (:meth:`GraphLayer.node_major_weights`,
:meth:`GraphLayer.forward_node_major`, and :mod:`nlo_lab.model.numpy_backend`) when
asked for it (``GraphDecoder.forward(z, form=...)``); called as ``decoder(z)`` it runs this form.
"""

from __future__ import annotations

import math

import torch
from torch import nn

from nlo_lab.errors import SettingsError
from nlo_lab.graph import Graph

__all__ = [
    "ACTIVATIONS",
    "DEFAULT_ACTIVATION",
    "activation_function",
    "GraphLayer",
    "GraphBuffers",
    "mlp",
    "remap_to_limits",
    "remap",
    "rest_preactivation",
    "LEAKY_SLOPE",
    "NUM_NODE_TYPES",
]

NUM_NODE_TYPES = 2  # NODE_ARM, NODE_HAND
LEAKY_SLOPE = 0.2  # negative slope of the LeakyReLU in the messages
ACTIVATIONS = ("sigmoid", "tanh", "relu", "leaky_relu")  # the paper's Table II, in its order
DEFAULT_ACTIVATION = "leaky_relu"  # the paper's g (and every shipped checkpoint's)


def activation_function(name: str):
    """The message activation ``g`` named ``name`` (one of :data:`ACTIVATIONS`) as a function of a tensor.

    Raises:
        SettingsError: an unknown name.
    """
    if name == "leaky_relu":
        return lambda x: nn.functional.leaky_relu(x, LEAKY_SLOPE)
    if name in ("sigmoid", "tanh", "relu"):
        return getattr(torch, name)

    raise SettingsError(f"unknown activation {name!r}; expected one of {', '.join(ACTIVATIONS)}")


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
    return remap(a, (lower + upper) * 0.5, (upper - lower) * 0.5, lower, upper)


def remap(a: torch.Tensor, mid: torch.Tensor, half: torch.Tensor, lower: torch.Tensor, upper: torch.Tensor) -> torch.Tensor:
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

    The weight of type ``t`` is one matrix ``W_t = [W_self | W_nbr | W_edge]``
    ``(O, 2 C_in + F)`` over the concatenation ``[x_i, x_j, e_ji]``.

    Args:
        in_features: node feature width C_in.
        out_features: node feature width C_out (O).
        edge_features: edge feature width F.
        activation: the message activation ``g``, one of :data:`ACTIVATIONS` (paper: LeakyReLU).
    """

    def __init__(self, in_features: int, out_features: int, edge_features: int, activation: str = DEFAULT_ACTIVATION):
        super().__init__()
        self.in_features, self.out_features, self.edge_features = in_features, out_features, edge_features
        self.activation = activation
        self.g = activation_function(activation)
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

    def forward(self, x: torch.Tensor, edge_index: torch.Tensor, edge_attr: torch.Tensor, node_type: torch.Tensor) -> torch.Tensor:
        """``x_i' = P_t x_i + sum_{j -> i} g(W_t [x_i, x_j, e_ji] + b_t)``, ``t`` = type of ``i``.

        Args:
            x: ``(B, N, C_in)`` node features.
            edge_index: ``(2, E)`` source j -> target i.
            edge_attr: ``(E, F)`` static or ``(B, E, F)`` per-sample edge features.
            node_type: ``(N,)`` :data:`~nlo_lab.graph.NODE_ARM` / :data:`~nlo_lab.graph.NODE_HAND`.

        Returns:
            ``(B, N, C_out)``.
        """
        B, N, _ = x.shape
        src, dst = edge_index[0], edge_index[1]  # j, i
        # index_select, not x[:, dst]: its backward sums in a fixed order (reproducible training)
        t = node_type.index_select(0, dst)  # (E,) the receiving node's type picks the weights
        e = edge_attr.to(x.dtype).expand(B, -1, -1)  # (B, E, F)
        h = torch.cat([x.index_select(1, dst), x.index_select(1, src), e], dim=-1)  # (B, E, 2C+F): [x_i, x_j, e_ji]
        w, b = self.weight.index_select(0, t), self.bias.index_select(0, t)  # (E, O, 2C+F), (E, O): W_t, b_t per edge
        msg = self.g(torch.einsum("bef,eof->beo", h, w) + b)  # (B, E, O): g = LeakyReLU in the paper
        total = x.new_zeros(B, N, self.out_features).index_add(1, dst, msg)  # sum over j in N(i)
        residual = x if self.skip is None else torch.einsum("bnc,noc->bno", x, self.skip.index_select(0, node_type))
        return residual + total

    def node_major_weights(
        self, edge_index: torch.Tensor, edge_attr: torch.Tensor, node_type: torch.Tensor, fixed: torch.Tensor | None = None
    ) -> dict:
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
            ``C' = C_in - D``; ``one_in``: every node receives exactly one message (the robots'
            structure graphs), the edges then in the order of their receiving nodes (``dst = 0..N-1``).
        """
        src, dst = edge_index[0], edge_index[1]
        one_in = dst.numel() == len(node_type) and bool((torch.bincount(dst, minlength=len(node_type)) == 1).all())
        if one_in:
            order = torch.argsort(dst)
            src, dst, edge_attr = src[order], dst[order], edge_attr[order]
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
            "one_in": one_in,
        }

    def forward_node_major(self, x: torch.Tensor, w: dict[str, torch.Tensor]) -> torch.Tensor:
        """The layer on node-major features: ``x (N, B, C')`` -> ``(N, B, O)``.

        Same map as :meth:`forward` (with ``w`` from :meth:`node_major_weights`)
        in a handful of batched matmuls over edges and nodes, which at small
        batch is what matters (per-op overhead).
        """
        return node_major_sum(x, self.g(node_major_messages(x, w)), w)


def node_major_messages(x: torch.Tensor, w: dict[str, torch.Tensor]) -> torch.Tensor:
    """:meth:`GraphLayer.forward_node_major`'s messages before the activation: ``x (N, B, C')`` -> ``(E, B, O)``."""
    receivers = x if w["one_in"] else x.index_select(0, w["dst"])  # one_in: edge i is node i's message
    msg = torch.baddbmm(w["bias"], receivers, w["self"])  # (E, B, O)
    return torch.baddbmm(msg, x.index_select(0, w["src"]), w["nbr"])


def node_major_sum(x: torch.Tensor, msg: torch.Tensor, w: dict[str, torch.Tensor]) -> torch.Tensor:
    """:meth:`GraphLayer.forward_node_major`'s output: the skip path of ``x (N, B, C')`` plus each node's
    activated messages ``msg (E, B, O)`` -> ``(N, B, O)``."""
    if w["skip"] is None:
        res = x
    elif w["skip_bias"] is None:
        res = torch.bmm(x, w["skip"])
    else:
        res = torch.baddbmm(w["skip_bias"], x, w["skip"])
    return res + msg if w["one_in"] else res.index_add(0, w["dst"], msg)  # + sum over incoming edges


class GraphBuffers(nn.Module):
    """A graph's tensors as (non-persistent) buffers, so that ``.to()`` moves them.

    Attributes:
        node_names: one name per node.
        edge_index: ``(2, E)`` long, source -> target.
        edge_attr: ``(E, F)`` float32 static edge features.
        node_type: ``(N,)`` long.
    """

    edge_index: torch.Tensor  # a buffer (typed here: nn.Module's __getattr__ says Tensor | Module)
    edge_attr: torch.Tensor
    node_type: torch.Tensor

    def __init__(self, graph: Graph):
        super().__init__()
        self.node_names = tuple(graph.node_names)
        self.register_buffer("edge_index", graph.edge_index.long().clone(), persistent=False)
        self.register_buffer("edge_attr", graph.edge_attr.float().clone(), persistent=False)
        self.register_buffer("node_type", graph.node_type.long().clone(), persistent=False)


class _Activation(nn.Module):
    """:func:`activation_function` as a module (for ``nn.Sequential``)."""

    def __init__(self, name: str):
        super().__init__()
        self.name, self.g = name, activation_function(name)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.g(x)

    def extra_repr(self) -> str:
        return self.name


def mlp(dims: tuple[int, ...], activation: str = DEFAULT_ACTIVATION) -> nn.Sequential:
    """Linear layers ``dims[0] -> ... -> dims[-1]`` with the activation between them (not after the last)."""
    mods: list[nn.Module] = []
    for i, (a, b) in enumerate(zip(dims[:-1], dims[1:], strict=True)):
        mods.append(nn.Linear(a, b))
        if i < len(dims) - 2:
            mods.append(nn.LeakyReLU(LEAKY_SLOPE) if activation == DEFAULT_ACTIVATION else _Activation(activation))
    return nn.Sequential(*mods)
