"""The decoder's forms: called directly it runs the paper's layers (a debugger stepping
through ``GraphDecoder.forward`` enters ``GraphLayer.forward``); asked for, the node-major
and numpy forms give the same values and gradients."""

from __future__ import annotations

import sys

import pytest
import torch

from nlo_lab.errors import SettingsError
from nlo_lab.model import DECODER_FORMS, GraphDecoder, MLPDecoder
from nlo_lab.model.layers import GraphLayer
from nlo_lab.model.numpy_backend import DecoderPlan

ROBOTS = ("yumi", "nao", "pepper")


@pytest.fixture(scope="module", params=ROBOTS)
def robot(request, robot64):
    return robot64(request.param)


def _decoder(robot, frozen: bool = True) -> GraphDecoder:
    torch.manual_seed(0)
    dec = GraphDecoder(robot.graph, robot.lower_limits, robot.upper_limits, latent_per_node=3, widths=(16, 8, 1),
                       rest=robot.neutral_q).to(torch.float64)
    for p in dec.parameters():
        p.requires_grad_(not frozen)
    return dec


def _value_and_grad(dec, z, form):
    x = z.detach().clone().requires_grad_(True)
    q = dec(x, form=form)
    w = torch.linspace(0.5, 1.5, q.numel(), dtype=q.dtype).view_as(q)
    (g,) = torch.autograd.grad((q * w).sum(), x)
    return q.detach(), g


def _stepped_into(fn) -> set:
    """The code objects a debugger stepping through ``fn()`` enters (sys.settrace, as pdb's step)."""
    entered = set()

    def tracer(frame, event, arg):
        if event == "call":
            entered.add(frame.f_code)
        return None

    sys.settrace(tracer)
    try:
        fn()
    finally:
        sys.settrace(None)
    return entered


@pytest.mark.parametrize("batch", [1, 3, 12])
def test_faster_forms_equal_the_paper_form(robot, batch):
    dec = _decoder(robot)
    z = 2 * torch.randn(batch, robot.n_joints, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(8))
    ref = _value_and_grad(dec, z, "paper")
    for form in ("node-major", "numpy"):
        fast = _value_and_grad(dec, z, form)
        for a, b in zip(fast, ref, strict=True):
            torch.testing.assert_close(a, b, atol=1e-10, rtol=1e-10)
    assert float(ref[1].abs().max()) > 0


def test_stepping_through_the_decoder_enters_the_graph_layers(robot):
    """What a learner's debugger sees: GraphDecoder.forward -> paper_preactivation -> GraphLayer.forward."""
    z = torch.zeros(1, robot.n_joints, 3, dtype=torch.float64)
    for frozen in (True, False):  # at inference (frozen) and in training alike
        dec = _decoder(robot, frozen)
        entered = _stepped_into(lambda dec=dec: dec(z))
        assert GraphDecoder.forward.__code__ in entered
        assert GraphDecoder.paper_preactivation.__code__ in entered
        assert GraphLayer.forward.__code__ in entered
        assert GraphLayer.forward_node_major.__code__ not in entered
        assert DecoderPlan.forward.__code__ not in entered
    fast = _stepped_into(lambda: _decoder(robot)(z, form="numpy"))  # asked for: the numpy form instead
    assert DecoderPlan.forward.__code__ in fast and GraphLayer.forward.__code__ not in fast


def test_the_paper_form_runs_every_layer_in_order(robot, monkeypatch):
    dec = _decoder(robot)
    calls = []
    paper_forward = GraphLayer.forward
    monkeypatch.setattr(GraphLayer, "forward", lambda self, *a: calls.append(self) or paper_forward(self, *a))
    z = torch.zeros(2, robot.n_joints, 3, dtype=torch.float64)
    dec(z)
    dec.preactivation(z)
    assert calls == list(dec.layers) * 2


def test_numpy_form_declines_where_it_cannot_run(robot):
    """Trainable weights (the numpy form has no gradient for them): node-major runs, same numbers."""
    z = torch.randn(2, robot.n_joints, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(3))
    trainable = _decoder(robot, frozen=False)
    q = trainable(z, form="numpy")
    assert "Decode" not in type(q.grad_fn).__name__
    torch.testing.assert_close(q, trainable(z))


def test_unknown_form_is_refused_in_one_line(robot):
    z = torch.zeros(1, robot.n_joints, 3, dtype=torch.float64)
    for dec in (_decoder(robot), MLPDecoder(robot.graph, robot.lower_limits, robot.upper_limits, latent_per_node=3).double()):
        with pytest.raises(SettingsError, match="decoder form") as info:
            dec(z, form="fast")
        assert "\n" not in str(info.value)
        for form in DECODER_FORMS:  # the MLP has one form: every name runs it
            assert dec(z, form=form).shape == (1, robot.n_joints)


@pytest.mark.parametrize("edges", [
    [[0, 1, 2, 3, 4], [1, 2, 3, 4, 0]],  # every node receives one message (as the robots' graphs)
    [[0, 1, 2, 1, 4], [1, 2, 3, 4, 3]],  # a root (no message) and a node with two
], ids=["one-in", "general"])
def test_faster_forms_equal_the_paper_form_on_any_graph(edges):
    from nlo_lab.graph import NODE_ARM, NODE_HAND, Graph

    torch.manual_seed(4)
    edge_index = torch.tensor(edges)
    graph = Graph(tuple(f"j{i}" for i in range(5)), edge_index, torch.randn(5, 6), torch.tensor([NODE_ARM] * 3 + [NODE_HAND] * 2))
    lower, upper = -torch.rand(5) - 0.5, torch.rand(5) + 0.5
    dec = GraphDecoder(graph, lower, upper, latent_per_node=3, widths=(8, 4, 1)).double().requires_grad_(False)
    assert [w["one_in"] for w in dec._weights()["layers"]] == [edges == [[0, 1, 2, 3, 4], [1, 2, 3, 4, 0]]] * 3
    z = torch.randn(3, 5, 3, dtype=torch.float64)
    ref = _value_and_grad(dec, z, "paper")
    for form in ("node-major", "numpy"):
        for a, b in zip(_value_and_grad(dec, z, form), ref, strict=True):
            torch.testing.assert_close(a, b, atol=1e-10, rtol=1e-10)


def _written_value_and_grad(dec, z):
    written = dec.written()
    q, state = written.forward(z)
    w = torch.linspace(0.5, 1.5, q.numel(), dtype=q.dtype).view_as(q)
    return q, written.backward(w, state)


@pytest.mark.parametrize("batch", [1, 12])
def test_the_written_gradient_equals_autograd_through_the_paper_form(robot, batch):
    """WrittenDecoder (the node-major map without a graph, its gradient to z written out): the paper form's angles
    and autograd's gradient, on each robot and on a graph with a root and a node of two messages."""
    dec = _decoder(robot)
    z = 2 * torch.randn(batch, robot.n_joints, 3, dtype=torch.float64, generator=torch.Generator().manual_seed(9))
    ref = _value_and_grad(dec, z, "paper")
    got = _written_value_and_grad(dec, z)
    for a, b in zip(got, ref, strict=True):
        torch.testing.assert_close(a, b, atol=1e-10, rtol=1e-10)
    assert float(ref[1].abs().max()) > 0
    assert not got[0].requires_grad  # no autograd graph


def test_the_written_gradient_equals_autograd_on_any_graph():
    from nlo_lab.graph import NODE_ARM, NODE_HAND, Graph

    torch.manual_seed(5)
    edge_index = torch.tensor([[0, 1, 2, 1, 4], [1, 2, 3, 4, 3]])  # a root (no message) and a node with two
    graph = Graph(tuple(f"j{i}" for i in range(5)), edge_index, torch.randn(5, 6), torch.tensor([NODE_ARM] * 3 + [NODE_HAND] * 2))
    dec = GraphDecoder(graph, -torch.rand(5) - 0.5, torch.rand(5) + 0.5, latent_per_node=3, widths=(8, 4, 1)).double()
    dec.requires_grad_(False)
    z = 3 * torch.randn(4, 5, 3, dtype=torch.float64)  # some angles at their limits (the clamp)
    for a, b in zip(_written_value_and_grad(dec, z), _value_and_grad(dec, z, "paper"), strict=True):
        torch.testing.assert_close(a, b, atol=1e-10, rtol=1e-10)


def test_the_written_gradient_declines_where_it_cannot_run(robot):
    """Trainable weights, or another activation than LeakyReLU: None (autograd runs)."""
    assert _decoder(robot).written() is not None
    assert _decoder(robot, frozen=False).written() is None
    sigmoid = GraphDecoder(robot.graph, robot.lower_limits, robot.upper_limits, latent_per_node=3, widths=(16, 8, 1),
                           activation="sigmoid").double().requires_grad_(False)
    assert sigmoid.written() is None
