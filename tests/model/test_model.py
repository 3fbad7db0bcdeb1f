"""Networks: the graph layer, encoders, decoders and the limit remap."""

from __future__ import annotations

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from nlo_lab.errors import SettingsError
from nlo_lab.graph import NODE_ARM, NODE_HAND, Graph
from nlo_lab.model import GraphDecoder, GraphLayer, MLPDecoder, build_model, remap_to_limits


def chain_graph(n: int = 5, edge_f: int = 6, hand_from: int = 3) -> Graph:
    """0 -> 1 -> 2 -> 3, 1 -> 4: a small tree, nodes >= hand_from are hand nodes."""
    edges = torch.tensor([[0, 1, 2, 1], [1, 2, 3, 4]])[:, : n - 1]
    types = torch.tensor([NODE_HAND if i >= hand_from else NODE_ARM for i in range(n)])
    return Graph(tuple(f"j{i}" for i in range(n)), edges, torch.randn(edges.shape[1], edge_f), types)


LOWER = torch.tensor([-2.9, -2.5, -0.1, 0.0, -5.06])
UPPER = torch.tensor([2.9, 0.76, 0.1, 1.47, 5.06])


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(allow_nan=False, allow_infinity=True, width=32), min_size=5, max_size=5))
def test_remap_never_leaves_limits(values):
    a = torch.tensor([values], dtype=torch.float32)
    q = remap_to_limits(a, LOWER, UPPER)
    assert torch.all(q >= LOWER) and torch.all(q <= UPPER)


@settings(max_examples=60, deadline=None)
@given(
    scale=st.sampled_from([1e-3, 1.0, 10.0, 1e3, 1e6]),
    seed=st.integers(0, 2**31 - 1),
    kind=st.sampled_from(["graph", "mlp"]),
)
def test_decoder_output_inside_limits_for_any_latent(scale, seed, kind):
    torch.manual_seed(0)
    g = chain_graph()
    dec = (GraphDecoder if kind == "graph" else MLPDecoder)(g, LOWER, UPPER, latent_per_node=3)
    z = torch.randn(7, 5, 3, generator=torch.Generator().manual_seed(seed)) * scale
    q = dec(z)
    assert q.shape == (7, 5)
    assert torch.all(q >= LOWER) and torch.all(q <= UPPER)


def test_remap_is_the_linear_map_of_tanh():
    a = torch.tensor([[0.0, 0.3, -0.7, 1.2, -2.0]], dtype=torch.float64)
    lo, hi = LOWER.double(), UPPER.double()
    expected = lo + (hi - lo) * (torch.tanh(a) + 1) / 2
    torch.testing.assert_close(remap_to_limits(a, lo, hi), expected)


def test_graph_layer_matches_the_formula():
    torch.manual_seed(1)
    g = chain_graph()
    layer = GraphLayer(4, 4, 6).double()
    x = torch.randn(2, 5, 4, dtype=torch.float64)
    e = g.edge_attr.double()
    out = layer(x, g.edge_index, e, g.node_type)
    expected = x.clone()
    for k, (j, i) in enumerate(g.edge_index.T.tolist()):
        t = int(g.node_type[i])
        h = torch.cat([x[:, i], x[:, j], e[k].expand(2, -1)], -1)
        expected[:, i] += torch.nn.functional.leaky_relu(h @ layer.weight[t].T + layer.bias[t], 0.2)
    torch.testing.assert_close(out, expected)


def test_graph_layer_messages_flow_source_to_target_only():
    torch.manual_seed(2)
    g = chain_graph()
    layer = GraphLayer(4, 8, 6)
    x = torch.randn(1, 5, 4)
    x2 = x.clone()
    x2[0, 3] += 1.0  # node 3 is a leaf: it sends nothing
    out, out2 = layer(x, g.edge_index, g.edge_attr, g.node_type), layer(x2, g.edge_index, g.edge_attr, g.node_type)
    changed = (out - out2).abs().sum(-1)[0] > 1e-7
    assert changed.tolist() == [False, False, False, True, False]
    x3 = x.clone()
    x3[0, 1] += 1.0  # node 1 feeds nodes 2 and 4
    out3 = layer(x3, g.edge_index, g.edge_attr, g.node_type)
    assert ((out - out3).abs().sum(-1)[0] > 1e-7).tolist() == [False, True, True, False, True]


def test_graph_layer_skip_projection_matches_the_formula():
    torch.manual_seed(6)
    g = chain_graph()
    layer = GraphLayer(3, 5, 6).double()
    x = torch.randn(2, 5, 3, dtype=torch.float64)
    e = g.edge_attr.double()
    out = layer(x, g.edge_index, e, g.node_type)
    expected = torch.stack([x[:, i] @ layer.skip[int(g.node_type[i])].T for i in range(5)], dim=1)
    for k, (j, i) in enumerate(g.edge_index.T.tolist()):
        t = int(g.node_type[i])
        h = torch.cat([x[:, i], x[:, j], e[k].expand(2, -1)], -1)
        expected[:, i] += torch.nn.functional.leaky_relu(h @ layer.weight[t].T + layer.bias[t], 0.2)
    torch.testing.assert_close(out, expected)


def test_static_and_per_sample_edges_agree_and_batch_equals_loop():
    torch.manual_seed(3)
    g = chain_graph()
    layer = GraphLayer(3, 5, 6).double()
    x = torch.randn(4, 5, 3, dtype=torch.float64)
    e = g.edge_attr.double()
    a = layer(x, g.edge_index, e, g.node_type)
    b = layer(x, g.edge_index, e.expand(4, -1, -1), g.node_type)
    c = torch.cat([layer(x[i : i + 1], g.edge_index, e, g.node_type) for i in range(4)])
    torch.testing.assert_close(a, b)
    torch.testing.assert_close(a, c)


def test_node_types_use_separate_weights():
    torch.manual_seed(4)
    g = chain_graph()
    layer = GraphLayer(4, 4, 6)
    x = torch.randn(1, 5, 4)
    out = layer(x, g.edge_index, g.edge_attr, g.node_type)
    with torch.no_grad():
        layer.weight[NODE_HAND].add_(1.0)
    out2 = layer(x, g.edge_index, g.edge_attr, g.node_type)
    changed = ((out - out2).abs().sum(-1)[0] > 1e-7).tolist()
    # Receivers of type hand (3, 4) change; arm receivers (1, 2) and the root (0) do not.
    assert changed == [False, False, False, True, True]


@pytest.mark.parametrize("kind", ["graph", "mlp"])
@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_model_shapes_dtypes_and_gradients_reach_z(kind, dtype):
    torch.manual_seed(5)
    human = Graph(tuple("abcdefg"), torch.tensor([[0, 1, 2, 0, 4, 5], [1, 2, 3, 4, 5, 6]]), torch.randn(6, 3), torch.tensor([0, 0, 0, 1, 0, 0, 1]))
    model = build_model("toy", chain_graph(), LOWER, UPPER, human, in_features=6, kind=kind, latent_per_node=4).to(dtype)
    x, e = torch.randn(3, 7, 6, dtype=dtype), torch.randn(3, 6, 3, dtype=dtype)
    q, z = model(x, e)
    assert q.shape == (3, 5) and z.shape == (3, 5, 4) and q.dtype == dtype
    assert model.latent_shape == (5, 4)
    z = torch.randn(3, 5, 4, dtype=dtype, requires_grad=True)
    model.decode(z).pow(2).sum().backward()
    assert z.grad is not None and torch.isfinite(z.grad).all() and z.grad.abs().sum() > 0


def test_build_model_rejects_bad_settings():
    human = chain_graph(edge_f=3)
    with pytest.raises(SettingsError, match="kind"):
        build_model("toy", chain_graph(), LOWER, UPPER, human, 6, kind="transformer")
    with pytest.raises(SettingsError, match="latent_per_node"):
        build_model("toy", chain_graph(), LOWER, UPPER, human, 6, latent_per_node=0)
    with pytest.raises(SettingsError, match="limits"):
        GraphDecoder(chain_graph(), LOWER[:3], UPPER[:3])


def test_small_model_size():
    human = chain_graph(n=5, edge_f=3)
    model = build_model("toy", chain_graph(), LOWER, UPPER, human, 6)
    n = sum(p.numel() for p in model.parameters())
    assert 0 < n < 500_000


def _layer_by_layer_decoder(dec: GraphDecoder, z: torch.Tensor) -> torch.Tensor:
    """The paper's decoder written out: GraphLayer.forward on [z, lower, upper], tanh, remap."""
    g = dec.graph
    x = torch.cat([z, torch.stack([dec.lower, dec.upper], -1).expand(z.shape[0], -1, -1)], -1)
    for layer in dec.layers:
        x = layer(x, g.edge_index, g.edge_attr, g.node_type)
    return dec.lower + (dec.upper - dec.lower) * (torch.tanh(x[..., 0] + dec.rest_pre) + 1) / 2


@pytest.mark.parametrize("widths", [(32, 16, 1), (5, 5, 1)])  # (5, 5): an identity skip after the first layer
def test_decoder_fast_path_equals_layer_by_layer(widths):
    torch.manual_seed(8)
    g = chain_graph()
    dec = GraphDecoder(g, LOWER, UPPER, latent_per_node=3, widths=widths).double()
    z = torch.randn(6, 5, 3, dtype=torch.float64)
    torch.testing.assert_close(dec(z, form="node-major"), _layer_by_layer_decoder(dec, z))
    # gradients of the parameters (training) agree too
    grads = torch.autograd.grad(dec(z, form="node-major").square().sum(), list(dec.parameters()))
    ref = torch.autograd.grad(_layer_by_layer_decoder(dec, z).square().sum(), list(dec.parameters()))
    for a, b in zip(grads, ref, strict=True):
        torch.testing.assert_close(a, b)


def test_frozen_decoder_cache_follows_in_place_updates():
    torch.manual_seed(9)
    dec = GraphDecoder(chain_graph(), LOWER, UPPER, latent_per_node=3).double()
    for p in dec.parameters():
        p.requires_grad_(False)
    z = torch.randn(2, 5, 3, dtype=torch.float64)
    first = dec(z, form="numpy")
    assert dec._weights() is dec._weights()  # frozen: built once
    with torch.no_grad():
        dec.layers[0].bias.add_(0.5)  # an optimiser step or load_state_dict
    second = dec(z, form="numpy")
    assert not torch.allclose(first, second)
    torch.testing.assert_close(second, _layer_by_layer_decoder(dec, z))


@pytest.mark.parametrize("widths", [(32, 16, 1), (5, 5, 1)])
@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_frozen_decoder_numpy_path_equals_torch_values_and_latent_gradients(widths, dtype):
    """The frozen decoder's numpy path (small batches, hand-written backward) = the torch ops."""
    from nlo_lab.inference.fast_paths import DECODER_NUMPY_MAX_BATCH

    torch.manual_seed(10)
    rest = LOWER + 0.3 * (UPPER - LOWER)  # a rest offset, as trained models have
    dec = GraphDecoder(chain_graph(), LOWER, UPPER, latent_per_node=3, widths=widths, rest=rest).to(dtype)
    for p in dec.parameters():
        p.requires_grad_(False)
    z = (3 * torch.randn(DECODER_NUMPY_MAX_BATCH, 5, 3, dtype=dtype)).requires_grad_(True)  # 3σ: some joints near a limit
    assert dec._weights().get("plan") is not None
    q = dec(z, form="numpy")
    assert q.grad_fn is not None and "Decode" in type(q.grad_fn).__name__  # the numpy path ran
    w = torch.randn_like(q)
    (g,) = torch.autograd.grad((q * w).sum(), z)
    ref_q = _layer_by_layer_decoder(dec, z)
    (ref_g,) = torch.autograd.grad((ref_q * w).sum(), z)
    tol = {} if dtype == torch.float64 else {"atol": 1e-5, "rtol": 1e-4}
    torch.testing.assert_close(q, ref_q, **tol)
    torch.testing.assert_close(g, ref_g, **tol)


def test_preactivation_then_remap_is_the_decoder():
    torch.manual_seed(11)
    for dec in (GraphDecoder(chain_graph(), LOWER, UPPER, latent_per_node=3), MLPDecoder(chain_graph(), LOWER, UPPER, latent_per_node=3)):
        z = torch.randn(4, 5, 3)
        a = dec.preactivation(z)
        assert a.shape == (4, 5)
        torch.testing.assert_close(dec.remap(a), dec(z))
        torch.testing.assert_close(dec.remap(a), remap_to_limits(a, LOWER, UPPER))


@pytest.mark.parametrize("cls", [GraphDecoder, MLPDecoder])
def test_a_silent_decoder_outputs_its_rest_pose(cls):
    """With every weight zero the decoder returns ``rest`` (within the ±0.9 clamp of the remap), else the midpoint."""
    rest = torch.tensor([1.0, -2.4, 0.0, 0.2, 4.9])  # the second and last lie beyond 0.9 of the half range
    dec = cls(chain_graph(), LOWER, UPPER, latent_per_node=3, rest=rest)
    plain = cls(chain_graph(), LOWER, UPPER, latent_per_node=3)
    with torch.no_grad():
        for d in (dec, plain):
            for p in d.parameters():
                p.zero_()
    z = torch.randn(2, 5, 3)
    mid, half = (LOWER + UPPER) / 2, (UPPER - LOWER) / 2
    expected = torch.minimum(torch.maximum(rest, mid - 0.9 * half), mid + 0.9 * half)
    torch.testing.assert_close(dec(z), expected.expand(2, -1), atol=1e-5, rtol=1e-5)
    torch.testing.assert_close(plain(z), mid.expand(2, -1), atol=1e-6, rtol=0)
