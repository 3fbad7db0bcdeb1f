"""The frozen graph decoder's gradient to the latent, written out in torch: no autograd graph.

Latent optimisation of a recording (:class:`~nlo_lab.inference.numpy_descent.WrittenGradientLoss`)
runs the decoder on every frame at once (a batch of ~50-200) with fixed weights and needs only
``dL/dz``. Autograd records some 20 nodes per call and runs its engine backward through them;
here the node-major map (:meth:`~nlo_lab.model.layers.GraphLayer.forward_node_major`, then the
tanh remap) runs without a graph, keeping what its derivative reads, and the derivative is the
same chain as :class:`~nlo_lab.model.numpy_backend.DecoderPlan`'s, in torch's batched products
(numpy's stacked small matmuls do not batch at these sizes).

Per layer, on node-major features ``x (N, B, C)``:
``m_e = b_e + x_dst W_self,e + x_src W_nbr,e`` per edge, ``a = LeakyReLU(m)``,
``y = x S + s + Σ_{e -> i} a_e``; then ``q = clamp(mid + half tanh(y + rest), lower, upper)``.
Backward: ``g_pre = g_q [lower <= q <= upper] half (1 - tanh²)``, per layer in reverse
``g_m = g_y[dst] LeakyReLU'(m)``, ``g_x = g_y Sᵀ + Σ_{e: dst = i} g_m W_selfᵀ + Σ_{e: src = i} g_m W_nbrᵀ``.

:meth:`GraphDecoder.written <nlo_lab.model.decoder.GraphDecoder.written>` builds it for frozen
weights and the default activation (LeakyReLU); the tests hold it equal to autograd through the
paper's form, values and gradients.
"""

from __future__ import annotations

import torch

from nlo_lab.model.layers import node_major_messages, node_major_sum

__all__ = ["WrittenDecoder"]


class WrittenDecoder:
    """``forward(z) -> (q, state)`` and ``backward(g_q, state) -> g_z`` of a frozen graph decoder.

    Args:
        weights: the decoder's node-major weight dict (``GraphDecoder._weights()``: ``layers``, ``mid``,
            ``half``, ``lower``, ``upper``, ``rest_pre``).
        slope: the LeakyReLU negative slope.
    """

    def __init__(self, weights: dict, slope: float):
        self.w, self.slope = weights, float(slope)
        # the transposed weights of the backward, made once
        self.back = [
            {
                "self_t": L["self"].mT.contiguous(),
                "nbr_t": L["nbr"].mT.contiguous(),
                "skip_t": None if L["skip"] is None else L["skip"].mT.contiguous(),
            }
            for L in weights["layers"]
        ]

    @torch.no_grad()
    def forward(self, z: torch.Tensor) -> tuple[torch.Tensor, tuple]:
        """``z (B, N, k)`` -> ``q (B, N)`` and what :meth:`backward` needs (no autograd graph)."""
        w = self.w
        x = z.transpose(0, 1)  # (N, B, k)
        saved = []
        for L in w["layers"]:
            m = node_major_messages(x, L)  # (E, B, O), kept: the activation's derivative reads it
            saved.append(m)
            x = node_major_sum(x, torch.nn.functional.leaky_relu(m, self.slope), L)
        t = torch.tanh(x[..., 0].T + w["rest_pre"])  # (B, N)
        pre = torch.addcmul(w["mid"], w["half"], t)
        q = torch.clamp(pre, min=w["lower"], max=w["upper"])
        return q, (saved, t, pre, x.shape[1])

    @torch.no_grad()
    def backward(self, g_q: torch.Tensor, state: tuple) -> torch.Tensor:
        """``(B, N, k)``: the gradient of ``sum(g_q * q)`` with respect to ``z``."""
        w = self.w
        saved, t, pre, B = state
        inside = (pre >= w["lower"]) & (pre <= w["upper"])  # torch.clamp passes the gradient there
        g_pre = torch.where(inside, g_q, 0.0) * w["half"] * (1.0 - t * t)  # (B, N)
        g_y = g_pre.T.unsqueeze(-1)  # (N, B, 1)
        for L, back, m in zip(reversed(w["layers"]), reversed(self.back), reversed(saved), strict=True):
            g_msg = g_y if L["one_in"] else g_y.index_select(0, L["dst"])  # (E, B, O)
            g_m = torch.ops.aten.leaky_relu_backward(g_msg, m, self.slope, False)  # g (m > 0) or slope g
            g_x = g_y if back["skip_t"] is None else torch.bmm(g_y, back["skip_t"])  # (N, B, C)
            g_self = torch.bmm(g_m, back["self_t"])  # onto the receiving nodes
            g_nbr = torch.bmm(g_m, back["nbr_t"])  # onto the sending nodes
            g_x = g_x + g_self if L["one_in"] else g_x.index_add(0, L["dst"], g_self)
            g_y = g_x.index_add(0, L["src"], g_nbr)
        return g_y.transpose(0, 1)
