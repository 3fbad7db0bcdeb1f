"""The frozen graph decoder in numpy, with a written-out backward to the latent.

Latent optimisation runs the decoder with fixed weights, at batch 1 in the
live panel. There each of its ~20 torch ops costs microseconds of dispatch plus
an autograd node in the backward, many times its arithmetic. This module runs
the same map (:meth:`nlo_lab.model.layers.GraphLayer.forward_node_major`, then the
tanh remap) in numpy inside one ``torch.autograd.Function`` whose backward
returns the gradient with respect to ``z`` only (the weights are frozen).

Per layer, on node-major features ``x (N, B, C)``:
``m_e = b_e + x_dst W_self,e + x_src W_nbr,e`` per edge, ``a = LeakyReLU(m)``,
``y = x S + s + A_dst a`` (``A_dst (N, E)`` sums the messages into their
receiving node); the last layer's ``y`` plus the rest offset goes through tanh. Backward: ``g_m = (A_dstᵀ g_y) * LeakyReLU'(m)``,
``g_x = g_y Sᵀ + A_dst (g_m W_selfᵀ) + A_src (g_m W_nbrᵀ)``.

:class:`~nlo_lab.model.decoder.GraphDecoder` takes this path when asked for it
(``form="numpy"``) for frozen weights on the CPU; the pipeline asks at small batches
(:class:`nlo_lab.inference.FastPaths`). The tests compare it with the paper's form,
values and gradients.
"""

from __future__ import annotations

import numpy as np
import torch
from torch.autograd.function import once_differentiable

__all__ = ["DecoderPlan", "decode_numpy"]


def _np(t: torch.Tensor | None) -> np.ndarray | None:
    return None if t is None else t.detach().cpu().numpy().copy()


class DecoderPlan:
    """Numpy copies of a decoder's node-major weights (built by ``GraphDecoder`` from its cached weights).

    Args:
        weights: the decoder's weight dict (``layers``, ``mid``, ``half``, ``lower``, ``upper``, ``rest_pre``).
        n_nodes: robot graph nodes ``N``.
        slope: the LeakyReLU negative slope.
    """

    def __init__(self, weights: dict, n_nodes: int, slope: float):
        self.slope = float(slope)
        self.dtype = _np(weights["mid"]).dtype
        self.layers = []
        for w in weights["layers"]:
            src, dst = w["src"].cpu().numpy(), w["dst"].cpu().numpy()
            a_src = np.zeros((n_nodes, len(src)), dtype=self.dtype)
            a_dst = np.zeros_like(a_src)
            a_src[src, np.arange(len(src))] = 1.0
            a_dst[dst, np.arange(len(dst))] = 1.0
            w_self, w_nbr, skip = _np(w["self"]), _np(w["nbr"]), _np(w["skip"])
            self.layers.append({
                "src": src, "dst": dst, "a_src": a_src, "a_dst": a_dst,
                "self": w_self, "nbr": w_nbr, "bias": _np(w["bias"]),
                "self_t": np.ascontiguousarray(w_self.swapaxes(1, 2)),
                "nbr_t": np.ascontiguousarray(w_nbr.swapaxes(1, 2)),
                "skip": skip, "skip_t": None if skip is None else np.ascontiguousarray(skip.swapaxes(1, 2)),
                "skip_bias": _np(w["skip_bias"]), "one_in": w["one_in"],
            })  # fmt: skip
        self.mid, self.half = _np(weights["mid"]), _np(weights["half"])
        self.lower, self.upper = _np(weights["lower"]), _np(weights["upper"])
        self.rest_pre = _np(weights["rest_pre"])

    def forward(self, z: np.ndarray):
        """``z (B, N, k)`` -> ``q (B, N)`` and what the backward needs."""
        x = np.ascontiguousarray(z.swapaxes(0, 1), dtype=self.dtype)  # (N, B, k)
        saved = []
        for L in self.layers:
            receivers = x if L["one_in"] else x[L["dst"]]  # one_in: edge i is node i's one message
            m = np.matmul(receivers, L["self"]) + np.matmul(x[L["src"]], L["nbr"]) + L["bias"]  # (E, B, O)
            a = np.where(m > 0, m, self.slope * m)
            if L["skip"] is None:
                res = x
            else:
                res = np.matmul(x, L["skip"])
                if L["skip_bias"] is not None:
                    res = res + L["skip_bias"]
            E, B, O = m.shape
            y = res + (a if L["one_in"] else (L["a_dst"] @ a.reshape(E, B * O)).reshape(-1, B, O))
            saved.append((x.shape[-1], m))
            x = y
        t = np.tanh(x[..., 0].T + self.rest_pre)  # (B, N)
        pre = self.mid + self.half * t
        q = np.minimum(np.maximum(pre, self.lower), self.upper)
        return q, (saved, t, pre)

    def backward(self, gq: np.ndarray, state) -> np.ndarray:
        """Gradient ``(B, N, k)`` of ``sum(gq * q)`` with respect to ``z``."""
        saved, t, pre = state
        inside = (pre >= self.lower) & (pre <= self.upper)  # torch.clamp passes the gradient there
        ga = np.where(inside, gq, 0.0) * self.half * (1.0 - t * t)  # (B, N)
        gy = np.ascontiguousarray(ga.T[..., None], dtype=self.dtype)  # (N, B, 1)
        for L, (c_in, m) in zip(reversed(self.layers), reversed(saved), strict=True):
            E, B, O = m.shape
            gm = (gy if L["one_in"] else gy[L["dst"]]) * np.where(m > 0, 1.0, self.slope).astype(self.dtype)  # (E, B, O)
            gx = gy if L["skip"] is None else np.matmul(gy, L["skip_t"])  # (N, B, C)
            g_self = np.matmul(gm, L["self_t"]).reshape(E, B * c_in)  # onto the receiving nodes
            g_nbr = np.matmul(gm, L["nbr_t"]).reshape(E, B * c_in)  # onto the sending nodes
            to_receivers = g_self if L["one_in"] else L["a_dst"] @ g_self
            gy = gx + (to_receivers + L["a_src"] @ g_nbr).reshape(-1, B, c_in)
        return gy.swapaxes(0, 1)


class _DecodeFn(torch.autograd.Function):
    @staticmethod
    def forward(ctx, z: torch.Tensor, plan: DecoderPlan):
        q, state = plan.forward(z.detach().numpy())
        ctx.plan, ctx.state = plan, state
        return torch.from_numpy(np.ascontiguousarray(q, dtype=plan.dtype))

    @staticmethod
    @once_differentiable  # a second derivative raises instead of coming out wrong
    def backward(ctx, grad: torch.Tensor):
        gz = ctx.plan.backward(grad.detach().numpy(), ctx.state)
        return torch.from_numpy(np.ascontiguousarray(gz, dtype=ctx.plan.dtype)), None


def decode_numpy(z: torch.Tensor, plan: DecoderPlan) -> torch.Tensor:
    """``q (B, N)`` from ``z (B, N, k)`` on the CPU (in the plan's dtype); differentiable in ``z``."""
    return _DecodeFn.apply(z, plan)
