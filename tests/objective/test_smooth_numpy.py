"""The numpy smoothness term (SmoothTerm) is the torch term: values and gradients, with and without an anchor frame."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from nlo_lab.objective import smoothness_loss
from nlo_lab.objective.numpy_backend import SmoothTerm
from nlo_lab.objective.weights import SMOOTH_MAX_STEP


@pytest.mark.parametrize("anchored", [False, True])
def test_smooth_term_values_and_gradients_are_the_torch_terms(anchored):
    gen = torch.Generator().manual_seed(0)
    T, n, fps, w = 9, 5, 30.0, 7.0
    limits = torch.tensor([1.0, 2.0, 5.0, float("inf"), 0.5], dtype=torch.float64)
    q = torch.randn(T, n, dtype=torch.float64, generator=gen) * 0.3
    q[4, 1] += 2.0  # a step far beyond SMOOTH_MAX_STEP: the steep part counts too
    anchor = torch.randn(n, dtype=torch.float64, generator=gen) if anchored else None
    term = SmoothTerm(fps, limits, w, anchor, torch.float64)
    g = torch.rand(T, dtype=torch.float64, generator=gen)  # any weights of the frames' terms
    value, state = term.forward(q.numpy())
    grad = term.backward(g.numpy(), state)
    qr = q.clone().requires_grad_(True)
    ref = w * (smoothness_loss(torch.cat([anchor[None], qr]), fps, limits)[1:] if anchored else smoothness_loss(qr, fps, limits))
    (ref_grad,) = torch.autograd.grad((ref * g).sum(), qr)
    np.testing.assert_allclose(value, ref.detach().numpy(), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(grad, ref_grad.numpy(), rtol=1e-12, atol=1e-12)
    assert float(np.abs(np.diff(q.numpy(), axis=0)).max()) > SMOOTH_MAX_STEP and float(np.abs(grad).max()) > 0
    assert (value[0] == 0) != anchored  # frame 0 pays a step only from an anchor
