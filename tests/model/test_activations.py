"""Table II's configurations: the message activation of the networks is a choice of the model.

Each activation of the paper's Table II (Sigmoid, Tanh, ReLU, LeakyReLU) builds, trains a step,
saves and loads, and is really the function the layers apply; shipped checkpoints (made before
the choice existed) still load as LeakyReLU; the numpy decoder declines any other activation.
"""

from __future__ import annotations

import pytest
import torch

from nlo_lab.corpus import sign_corpus
from nlo_lab.errors import CheckpointError, SettingsError
from nlo_lab.model import ACTIVATIONS, DEFAULT_ACTIVATION, GraphLayer, checkpoint_path, load_checkpoint, load_pretrained, save_checkpoint
from nlo_lab.training import TrainSettings, demos_inputs, new_model, train_model

REFERENCE = {  # written out here, independently of nlo_lab.model.layers
    "sigmoid": lambda x: 1 / (1 + torch.exp(-x)),
    "tanh": lambda x: (torch.exp(x) - torch.exp(-x)) / (torch.exp(x) + torch.exp(-x)),
    "relu": lambda x: x.clamp_min(0),
    "leaky_relu": lambda x: torch.where(x > 0, x, 0.2 * x),
}

pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def frames():
    """A few real frames of the synthetic training split, as training reads them."""
    data = demos_inputs(sign_corpus("train")[:1])
    return data.index(slice(0, 48)), data.index(slice(48, 64))


def test_the_paper_table_ii_activations_and_the_default():
    assert ACTIVATIONS == ("sigmoid", "tanh", "relu", "leaky_relu")
    assert DEFAULT_ACTIVATION == "leaky_relu" and TrainSettings().activation == "leaky_relu"


@pytest.mark.parametrize("activation", ACTIVATIONS)
def test_the_graph_layer_applies_the_chosen_activation_to_its_messages(nao, activation):
    torch.manual_seed(3)
    g = nao.graph
    layer = GraphLayer(4, 4, g.edge_attr.shape[-1], activation).double()
    x = torch.randn(2, g.num_nodes, 4, dtype=torch.float64)
    e = g.edge_attr.double()
    expected = x.clone()
    for k, (j, i) in enumerate(g.edge_index.T.tolist()):
        t = int(g.node_type[i])
        h = torch.cat([x[:, i], x[:, j], e[k].expand(2, -1)], -1)
        expected[:, i] += REFERENCE[activation](h @ layer.weight[t].T + layer.bias[t])
    torch.testing.assert_close(layer(x, g.edge_index, e, g.node_type), expected)


@pytest.mark.parametrize("kind", ["graph", "mlp"])
def test_the_same_weights_with_another_activation_decode_other_angles(nao, kind):
    models = {a: new_model(nao, TrainSettings(kind=kind, activation=a)) for a in ACTIVATIONS}
    state = models["leaky_relu"].state_dict()
    for m in models.values():
        m.load_state_dict(state)  # same parameters: only the activation differs
    z = torch.randn(5, *models["leaky_relu"].latent_shape, generator=torch.Generator().manual_seed(0))
    with torch.no_grad():
        q = {a: m.decode(z) for a, m in models.items()}
    for a in ACTIVATIONS:
        for b in ACTIVATIONS:
            if a < b:
                assert not torch.allclose(q[a], q[b]), f"{a} and {b} decode the same angles"


@pytest.mark.parametrize("activation", ACTIVATIONS)
def test_each_activation_trains_a_step_saves_and_loads(tmp_path, nao, frames, activation):
    train, val = frames
    settings = TrainSettings(activation=activation, max_steps=1, batch_size=16, val_frames=16, progress=False)
    result = train_model(nao, settings, train_data=train, val_data=val)
    assert result.steps == 1
    model = result.model
    assert model.config["activation"] == activation
    assert all(layer.activation == activation for layer in [*model.encoder.layers, *model.decoder.layers])
    before = new_model(nao, settings)
    changed = [k for k, v in model.state_dict().items() if v.is_floating_point() and not torch.equal(v, before.state_dict()[k])]
    assert any(k.startswith("decoder.layers") for k in changed), "one optimiser step moved no decoder weight"
    path = save_checkpoint(model, tmp_path / f"nao_{activation}.pt", nao)
    assert torch.load(path, weights_only=True)["model_config"]["activation"] == activation
    loaded = load_checkpoint(path, nao)
    assert loaded.config["activation"] == activation and loaded.decoder.activation == activation
    x = val.encoder
    with torch.no_grad():
        torch.testing.assert_close(loaded(x.node_features, x.edge_features)[0], model(x.node_features, x.edge_features)[0])


def test_a_shipped_checkpoint_from_before_the_choice_loads_as_leaky_relu():
    raw = torch.load(checkpoint_path("nao"), weights_only=True)
    model = load_pretrained("nao")
    assert model.decoder.activation == "leaky_relu" and model.encoder.activation == "leaky_relu"
    assert raw["model_config"].get("activation", "leaky_relu") == "leaky_relu"


def test_an_unknown_activation_is_refused_in_settings_and_in_a_checkpoint(tmp_path, nao):
    with pytest.raises(SettingsError, match="activation"):
        TrainSettings(activation="swish")
    path = save_checkpoint(new_model(nao), tmp_path / "nao.pt", nao)
    ckpt = torch.load(path, weights_only=True)
    ckpt["model_config"]["activation"] = "swish"
    torch.save(ckpt, path)
    with pytest.raises(CheckpointError, match="swish"):
        load_checkpoint(path, nao)


@pytest.mark.parametrize("activation", ACTIVATIONS)
def test_the_numpy_decoder_runs_for_the_default_only_and_every_form_gives_the_same_angles(nao, activation):
    model = new_model(nao, TrainSettings(activation=activation)).double()
    dec = model.decoder
    for p in dec.parameters():
        p.requires_grad_(False)
    assert (dec._weights().get("plan") is not None) == (activation == DEFAULT_ACTIVATION)
    z = torch.randn(2, *model.latent_shape, dtype=torch.float64, generator=torch.Generator().manual_seed(1)).requires_grad_(True)
    ref = dec(z)  # the paper's form: the layers one after the other
    w = torch.randn_like(ref)
    (ref_g,) = torch.autograd.grad((ref * w).sum(), z)
    for form in ("node-major", "numpy"):
        q = dec(z, form=form)
        took_numpy = "Decode" in type(q.grad_fn).__name__
        assert took_numpy == (form == "numpy" and activation == DEFAULT_ACTIVATION), (form, activation)
        torch.testing.assert_close(q, ref)
        torch.testing.assert_close(torch.autograd.grad((q * w).sum(), z)[0], ref_g)
