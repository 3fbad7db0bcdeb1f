# %% [markdown]
# # 06. Graphs against MLPs, FK against supervision
#
# ## Learning goals
#
# - See the two design choices the paper ablates (its Table III): a **graph** encoder/decoder over the
#   human skeleton and robot structure graphs against plain **MLPs**, and training through **forward
#   kinematics** on the objective against **supervised** fitting of an optimiser's angles.
# - Train the four variants AE, GAE, AE+FK, GAE+FK under the same wall-clock budget.
# - Compare each one's encoder output ('Init') with latent optimisation on top ('Optim') on unseen motions.

# %%
from nlo_lab.lab import TEST_MODE, budget, setup

setup()

# %% [markdown]
# ## Two architectures
#
# The graph layers share weights per node type and pass messages along the skeleton's edges (left wrist
# talks to left elbow, not to the right hand); the MLP flattens all 27 human nodes into one vector and
# learns every relation from data. Count the parameters:

# %%
from nlo_lab.robot import load_robot
from nlo_lab.training import TrainSettings, new_model

robot = load_robot("yumi")
for kind in ("graph", "mlp"):
    m = new_model(robot, TrainSettings(kind=kind))
    n_enc = sum(p.numel() for p in m.encoder.parameters())
    n_dec = sum(p.numel() for p in m.decoder.parameters())
    print(f"{kind:6s} encoder {n_enc:7d} parameters, decoder {n_dec:6d}, latent {m.latent_shape}")

# %% [markdown]
# ## The graph layer: equation and code
#
# One layer of the paper's encoder and decoder (Sec. "Graph-based Encoder & Decoder"), for node `i` of type
# `t` (arm or hand) with incoming edges from its neighbours `j`:
#
# $$x_i' = P_t\,x_i + \sum_{j \in N(i)} \mathrm{LeakyReLU}\big(W_t\,[x_i, x_j, e_{ji}] + b_t\big)$$
#
# `P_t` is the identity when the width does not change (the paper's residual), a learnt linear map when it
# does. This is the code that computes it:

# %%
import inspect

from nlo_lab.model import GraphLayer

print(inspect.getsource(GraphLayer.forward))

# %% [markdown]
# Called as `decode(z)`, the decoder runs the layers above one by one. Latent optimisation, which calls
# the frozen decoder every iteration, asks for the same map with its weights gathered per edge and its
# constant inputs folded in (`form="node-major"`), or that in numpy for a few frames (`form="numpy"`);
# the angles agree to rounding:

# %%
import torch

graph_model = new_model(robot, TrainSettings(kind="graph")).requires_grad_(False)
z = torch.randn(4, *graph_model.latent_shape)
paper = graph_model.decode(z)
for form in ("node-major", "numpy"):
    print(f"{form}: largest difference {float((graph_model.decode(z, form=form) - paper).abs().max()):.1e} rad")

# %% [markdown]
# ## Training data and labels
#
# FK training needs only the human frames: the loss is the objective `L(D, K(f_psi(f_phi(D))))`.
# Supervised training needs target angles: the paper's AE/GAE fit the output of an optimisation method;
# ours fit joint-space optimisation results (`nlo_lab.training.supervised_dataset`). Making them takes a while
# the first time (a progress bar shows it); they are then cached in your user cache folder.
# Both get the same frames.

# %%
from nlo_lab.training import SupervisedSettings, supervised_dataset

data, labels, label_seconds = supervised_dataset(robot, SupervisedSettings(frame_stride=budget(4, 64), label_iterations=budget(150, 20)),
                                                 progress=True)   # a bar the first time; then the labels come from the cache
print(f"{len(data)} training frames, labels {tuple(labels.shape)} made in {label_seconds:.1f} s")

# %% [markdown]
# ## Four variants, one budget
#
# Each variant trains for the same number of seconds: `SECONDS` each, so the cell takes about four times
# that (the bar fills with the time spent).

# %%
from nlo_lab.lab import time_bar
from nlo_lab.training import VARIANTS, train_variant

SECONDS = budget(60, 3)
variants = {}
with time_bar(SECONDS * len(VARIANTS), f"training {len(VARIANTS)} variants") as bar:
    for name in VARIANTS:
        bar.set_postfix_str(name)
        model, secs, steps = train_variant(robot, name, data, labels, SECONDS)
        variants[name] = model
        print(f"{name:7s} {secs:5.1f} s, {steps:5d} steps")

# %% [markdown]
# ## Init and Optim on unseen motions
#
# 'Init' decodes the encoder's latent (`encoder_only`); 'Optim' continues with latent optimisation through
# the frozen decoder (`latent_encoder`). The metric is the Fréchet distance of `docs/DESIGN.md`, "Metric" (wrist and elbow, mean).

# %%
from nlo_lab.corpus import corpus_clip, corpus_names
from nlo_lab.evaluation import BaselineSettings, run_method
from nlo_lab.metrics import tracking_errors

demos = [corpus_clip(n) for n in corpus_names("test")[: budget(4, 1)]]
demos = [d.slice(0, budget(len(d), 20)) for d in demos]
settings = BaselineSettings(iterations=budget(100, 10))
from tqdm.auto import tqdm

scores = {}
for name, model in tqdm(variants.items(), desc="scoring", total=len(variants)):
    for col, method in (("Init", "encoder_only"), ("Optim", "latent_encoder")):
        vals = [tracking_errors(d, robot, run_method(method, robot, d, settings, model=model).angles)["frechet_m"] for d in demos]
        scores[(name, col)] = sum(vals) / len(vals)
for name in variants:
    print(f"{name:7s} Init {scores[(name, 'Init')]:.4f} m   Optim {scores[(name, 'Optim')]:.4f} m")

# %%
import matplotlib.pyplot as plt
import numpy as np

fig, ax = plt.subplots(figsize=(6, 3.2))
x = np.arange(len(variants))
ax.bar(x - 0.2, [scores[(n, "Init")] for n in variants], 0.4, label="Init")
ax.bar(x + 0.2, [scores[(n, "Optim")] for n in variants], 0.4, label="Optim")
ax.set_xticks(x, list(variants)); ax.set_ylabel("mean Fréchet distance [m]"); ax.legend();

# %% [markdown]
# The paper (Table III) reports three findings. Do they hold in this run? Each row compares the pairs of
# variants the finding is about, on the mean Fréchet distance above (lower is better):

# %%
from IPython.display import Markdown

claims = {
    "FK training beats supervised fitting (Optim: AE+FK vs AE, GAE+FK vs GAE)":
        [(scores[(f"{k}+FK", "Optim")], scores[(k, "Optim")]) for k in ("AE", "GAE")],
    "graphs beat MLPs (Optim: GAE vs AE, GAE+FK vs AE+FK)":
        [(scores[("G" + k, "Optim")], scores[(k, "Optim")]) for k in ("AE", "AE+FK")],
    "latent optimisation improves on the encoder's output (Optim vs Init, every variant)":
        [(scores[(n, "Optim")], scores[(n, "Init")]) for n in variants],
}
rows = [f"| {claim} | {sum(a < b for a, b in pairs)} of {len(pairs)} |" for claim, pairs in claims.items()]
Markdown(f"With {SECONDS} s of training per variant and {len(demos)} test clip(s) of at most {max(len(d) for d in demos)} frames:\n\n"
         "| the paper's finding | pairs where it holds here |\n|---|---|\n" + "\n".join(rows) +
         "\n\nShort budgets and few clips make such a ranking depend on the run: change `SECONDS` or the clips and compare.")

# %% [markdown]
# ## Exercises
#
# 1. Double `SECONDS`. Predict which variant gains most: the supervised ones (more epochs on fixed labels)
#    or the FK ones (more steps on the objective)?
# 2. Make the labels worse with `label_iterations=10`. Which two variants change, and which cannot?
# 3. Count the parameters again with `latent_per_node=8`. Which architecture grows faster, and why?
# 4. Replace `latent_encoder` by `latent_random` in the Optim column: how much of 'Optim' comes from the
#    encoder's start?
