"""Decoders ``f_psi``: the latent code ``z (B, N_r, k)`` -> joint angles inside the limits.

* :class:`GraphDecoder`: the robot's structure graph, per-node input
  ``z_i ⊕ lower_i ⊕ upper_i``, widths 32 -> 16 -> 1
  (:class:`~nlo_lab.model.layers.GraphLayer`), ``tanh``, then
  :func:`~nlo_lab.model.layers.remap_to_limits`.
* :class:`MLPDecoder`: the plain fully connected variant of the ablation.

Called as ``decoder(z)`` the graph decoder runs the paper's form,
:meth:`GraphDecoder.paper_preactivation` (the layers'
:meth:`~nlo_lab.model.layers.GraphLayer.forward` one after the other): a debugger steps
into the equations. Latent optimisation calls the frozen decoder every iteration, so
the pipeline asks for a faster evaluation of the same map (``decoder(z, form=...)``,
chosen by :class:`nlo_lab.inference.FastPaths`): ``"node-major"``, node-major weights
with the constant inputs folded in (cached while the weights do not change), or
``"numpy"``, the same in numpy with a written-out gradient (:mod:`nlo_lab.model.numpy_backend`).
"""

from __future__ import annotations

import torch
from torch import nn

from nlo_lab.errors import SettingsError
from nlo_lab.graph import Graph
from nlo_lab.model.layers import DEFAULT_ACTIVATION, LEAKY_SLOPE, GraphBuffers, GraphLayer, mlp, remap, remap_to_limits, rest_preactivation
from nlo_lab.model.numpy_backend import DecoderPlan, decode_numpy
from nlo_lab.model.written_gradient import WrittenDecoder
from nlo_lab.settings import check_choice

__all__ = ["GraphDecoder", "MLPDecoder", "DECODER_FORMS"]

DECODER_FORMS = ("paper", "node-major", "numpy")  # the evaluations of one map; see GraphDecoder.forward


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
            in is the one it keeps (see :func:`~nlo_lab.model.layers.rest_preactivation`).
        activation: the layers' message activation (:data:`~nlo_lab.model.layers.ACTIVATIONS`;
            paper: LeakyReLU). The numpy evaluation of the frozen decoder supports the
            default only; with another one the decoder runs in torch.
    """

    lower: torch.Tensor  # a buffer (typed here: nn.Module's __getattr__ says Tensor | Module)
    upper: torch.Tensor
    rest_pre: torch.Tensor

    def __init__(
        self,
        robot_graph: Graph,
        lower: torch.Tensor,
        upper: torch.Tensor,
        latent_per_node: int = 4,
        widths: tuple[int, ...] = (32, 16, 1),
        rest: torch.Tensor | None = None,
        activation: str = DEFAULT_ACTIVATION,
    ):
        super().__init__()
        if widths[-1] != 1:
            raise SettingsError(f"the decoder's last width must be 1 (one angle per joint), got {widths}")
        n = robot_graph.num_nodes
        if lower.shape != (n,) or upper.shape != (n,):
            raise SettingsError(f"limits must be ({n},) like the robot graph, got {tuple(lower.shape)}/{tuple(upper.shape)}")
        self.graph = GraphBuffers(robot_graph)
        self.latent_per_node = latent_per_node
        self.register_buffer("lower", lower.detach().float().clone(), persistent=False)
        self.register_buffer("upper", upper.detach().float().clone(), persistent=False)
        self.register_buffer("rest_pre", rest_preactivation(rest, self.lower, self.upper))  # (n,), saved in checkpoints
        edge_f = robot_graph.edge_attr.shape[-1]
        dims = (latent_per_node + 2, *widths)
        self.activation = activation
        self.layers = nn.ModuleList(GraphLayer(a, b, edge_f, activation) for a, b in zip(dims[:-1], dims[1:], strict=True))

    @property
    def latent_shape(self) -> tuple[int, int]:
        """``(N_r, k)``: the shape of one sample's latent."""
        return (self.graph.node_type.shape[0], self.latent_per_node)

    def forward(self, z: torch.Tensor, form: str = "paper") -> torch.Tensor:
        """``z (B, N_r, k)`` -> ``q (B, n)`` [rad]: ``remap(preactivation(z))``.

        Args:
            z: the latent.
            form: which evaluation of the same map runs (:data:`DECODER_FORMS`):
                ``"paper"`` (the default): :meth:`paper_preactivation`, the layers as the
                paper writes them; ``"node-major"``: node-major weights with the constant
                inputs folded in (fewer, larger ops); ``"numpy"``: that in numpy with a
                written-out gradient to ``z`` (fastest at small batch), for frozen weights
                with ``z`` on the CPU in the weights' dtype and the default activation
                (LeakyReLU), else ``"node-major"`` runs.
        """
        if form == "paper":
            return self.remap(self.paper_preactivation(z))
        check_choice("decoder form", form, DECODER_FORMS)
        w = self._weights()
        plan = w.get("plan")  # frozen weights on the CPU: numpy with a written-out backward
        if form == "numpy" and plan is not None and z.device.type == "cpu" and z.dtype == w["mid"].dtype:
            return decode_numpy(z, plan)
        return remap(self._node_major_preactivation(z, w), w["mid"], w["half"], w["lower"], w["upper"])

    def paper_preactivation(self, z: torch.Tensor) -> torch.Tensor:
        """The decoder as the paper writes it: ``z (B, N_r, k)`` -> ``a (B, n)`` before tanh.

        Each node's input is ``x_i = z_i ⊕ lower_i ⊕ upper_i``; the layers'
        :meth:`GraphLayer.forward` run one after the other; the last width is 1,
        one number per joint, plus the rest offset.
        """
        g = self.graph
        limits = torch.stack([self.lower, self.upper], dim=-1).to(z.dtype).expand(z.shape[0], -1, -1)  # (B, N_r, 2)
        x = torch.cat([z, limits], dim=-1)  # (B, N_r, k + 2)
        for layer in self.layers:
            x = layer(x, g.edge_index, g.edge_attr, g.node_type)
        return x[..., 0] + self.rest_pre

    def preactivation(self, z: torch.Tensor, form: str = "paper") -> torch.Tensor:
        """``z (B, N_r, k)`` -> ``a (B, n)``, the values before tanh (``q = remap(a)``).

        Useful to see saturation: a joint whose ``a`` sits in tanh's flat tail is
        pinned at its limit and passes no gradient, in training or to the latent.
        ``form``: as :meth:`forward` (``"numpy"`` runs ``"node-major"`` here).
        """
        if form == "paper":
            return self.paper_preactivation(z)
        check_choice("decoder form", form, DECODER_FORMS)
        return self._node_major_preactivation(z, self._weights())

    def remap(self, a: torch.Tensor) -> torch.Tensor:
        """``a (B, n)`` -> ``q (B, n)`` inside the limits (tanh, then the linear remap)."""
        return remap_to_limits(a, self.lower, self.upper)

    def numpy_plan(self) -> DecoderPlan | None:
        """The ``"numpy"`` form's arrays (:class:`~nlo_lab.model.numpy_backend.DecoderPlan`: forward and
        the gradient to ``z``) while the weights are frozen and on the CPU; None otherwise."""
        return self._weights().get("plan")

    def written(self) -> WrittenDecoder | None:
        """The ``"node-major"`` form without an autograd graph and its gradient to ``z`` written out
        (:class:`~nlo_lab.model.written_gradient.WrittenDecoder`) while the weights are frozen and the
        activation is the default (LeakyReLU); None otherwise."""
        return self._weights().get("written")

    def _node_major_preactivation(self, z: torch.Tensor, w: dict) -> torch.Tensor:
        x = z.transpose(0, 1)  # (N_r, B, k): node-major, see GraphLayer.forward_node_major
        for layer, wl in zip(self.layers, w["layers"], strict=True):
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
            if self.activation == DEFAULT_ACTIVATION:  # the written-out gradients: LeakyReLU only
                w["written"] = WrittenDecoder(w, LEAKY_SLOPE)
                if self.lower.device.type == "cpu":  # numpy: the CPU only
                    w["plan"] = DecoderPlan(w, len(g.node_type), LEAKY_SLOPE)
            self._weights_cache = (key, w)
        return w


class MLPDecoder(nn.Module):
    """Plain fully connected decoder (ablation): ``z ⊕ lower ⊕ upper`` -> tanh -> remap."""

    lower: torch.Tensor  # a buffer (typed here: nn.Module's __getattr__ says Tensor | Module)
    upper: torch.Tensor
    rest_pre: torch.Tensor

    def __init__(
        self,
        robot_graph: Graph,
        lower: torch.Tensor,
        upper: torch.Tensor,
        latent_per_node: int = 4,
        widths: tuple[int, ...] = (128, 64),
        rest: torch.Tensor | None = None,
        activation: str = DEFAULT_ACTIVATION,
    ):
        super().__init__()
        n = robot_graph.num_nodes
        self.n_nodes, self.latent_per_node = n, latent_per_node
        self.register_buffer("lower", lower.detach().float().clone(), persistent=False)
        self.register_buffer("upper", upper.detach().float().clone(), persistent=False)
        self.register_buffer("rest_pre", rest_preactivation(rest, self.lower, self.upper))
        self.activation = activation
        self.net = mlp((n * (latent_per_node + 2), *widths, n), activation)

    @property
    def latent_shape(self) -> tuple[int, int]:
        """``(N_r, k)``."""
        return (self.n_nodes, self.latent_per_node)

    def forward(self, z: torch.Tensor, form: str = "paper") -> torch.Tensor:
        """``z (B, N_r, k)`` -> ``q (B, n)`` [rad]; one form (``form`` is checked, for the graph decoder's interface)."""
        return self.remap(self.preactivation(z, form))

    def preactivation(self, z: torch.Tensor, form: str = "paper") -> torch.Tensor:
        """``z (B, N_r, k)`` -> ``a (B, n)`` before tanh (see :meth:`GraphDecoder.preactivation`)."""
        check_choice("decoder form", form, DECODER_FORMS)
        B = z.shape[0]
        lim = torch.stack([self.lower, self.upper], dim=-1).expand(B, -1, -1)
        return self.net(torch.cat([z, lim], dim=-1).flatten(1)) + self.rest_pre

    def remap(self, a: torch.Tensor) -> torch.Tensor:
        """``a (B, n)`` -> ``q (B, n)`` inside the limits."""
        return remap_to_limits(a, self.lower, self.upper)
