# %% [markdown]
# # 02. Human demonstrations
#
# ## Learning goals
#
# - Know the data model of a demonstration: per arm shoulder, elbow, wrist positions `(T, 3)` [m], wrist
#   orientation `(T, 3, 3)`, five fingers' base and tip `(T, 5, 2, 3)`, and validity masks.
# - Explore the synthetic sign corpus (train and test scenarios, handshapes) used to train the model.
# - Read a real MediaPipe Holistic recording (`.pose`) and see where it is incomplete.
# - Read the human skeleton graph and the per-node features the encoder sees.

# %%
from nlo_lab.lab import TEST_MODE, budget, setup

setup()

# %% [markdown]
# ## The synthetic sign corpus
#
# Sequences of signs (handshape, location, movement, two-handed pattern) performed by simulated signers
# with different bodies. The test scenarios only use sign combinations never seen in training.
# It is its own stage, `nlo_lab.corpus`, built on the `nlo_lab.human` data model.

# %%
from nlo_lab.corpus import corpus_clip, corpus_names

train, test = corpus_names("train"), corpus_names("test")
print(f"{len(train)} train and {len(test)} test sequences, e.g. {train[:3]}")
demo = corpus_clip(test[0])
print(demo.name, len(demo), "frames at", demo.fps, "fps; signs:", demo.meta["signs"])

# %% [markdown]
# The right wrist of a few sequences, relative to the right shoulder, over time.

# %%
import matplotlib.pyplot as plt
import numpy as np

fig, axes = plt.subplots(1, 3, figsize=(10, 3), sharey=True)
for name in test[: budget(4, 2)]:
    d = corpus_clip(name)
    rel = d.arm_positions[:, 1, 2] - d.arm_positions[:, 1, 0]      # (T, 3) right wrist - right shoulder [m]
    t = np.arange(len(d)) / d.fps
    for k, ax in enumerate(axes):
        ax.plot(t, rel[:, k], label=name)
for ax, c in zip(axes, "xyz", strict=True):
    ax.set(title=f"{c} [m]", xlabel="time [s]")
axes[0].legend(fontsize="x-small"); fig.tight_layout()

# %% [markdown]
# ### Handshapes
#
# A handshape is four angles per finger: flexion at the base, spread, and two more flexions [rad].

# %%
from nlo_lab.corpus import HANDSHAPES

names = list(HANDSHAPES)[:8]
fig, axes = plt.subplots(1, len(names), figsize=(1.6 * len(names), 2.2), sharey=True)
for ax, name in zip(axes, names, strict=True):
    ax.imshow(np.degrees(HANDSHAPES[name]), vmin=-30, vmax=110, cmap="viridis")
    ax.set(title=name, xticks=range(4), yticks=range(5))
axes[0].set_yticklabels(["thumb", "index", "middle", "ring", "pinky"]); fig.tight_layout()

# %%
from nlo_lab.lab import show_human

show_human(demo)

# %% [markdown]
# ## A real MediaPipe recording
#
# `assets/recordings/` holds one short public recording of the pose-format project (MIT licence).
# Coordinates from a monocular video are not in metres and depth is noisy; the reader builds the body
# frame (origin between the shoulders, X forward, Y left, Z up) and marks missing points in the masks.

# %%
from nlo_lab.human import load_demonstration
from nlo_lab.lab import recording_path

real = load_demonstration(recording_path())
print(real.name, len(real), "frames at", real.fps, "fps")
print("arm points observed:   ", f"{real.arm_mask.mean():.0%}")
print("finger points observed:", f"{real.finger_mask.mean():.0%}")

# %%
fig, ax = plt.subplots(figsize=(6, 2.5))
for s, side in enumerate(("left", "right")):
    ax.plot(real.finger_mask[:, s].reshape(len(real), -1).mean(1), label=f"{side} hand")
ax.set(xlabel="frame", ylabel="fingers observed", ylim=(-0.05, 1.05)); ax.legend();

# %%
show_human(real)

# %% [markdown]
# ## The skeleton graph
#
# The encoder reads the demonstration as a graph: 27 nodes (torso; per side shoulder, elbow, wrist and the
# five fingers' base and tip). Each node carries 13 features: its position normalised by arm length (3),
# the wrist rotation (9) and a validity flag (1).

# %%
from nlo_lab.human import NODE_NAMES, node_features, skeleton_graph
from nlo_lab.lab import plot_graph

plot_graph(skeleton_graph(), NODE_NAMES, title="human skeleton graph");
print("node features of the real recording:", node_features(real).shape)

# %% [markdown]
# For the metric (`docs/DESIGN.md`, "Metric"), the human arm is mapped into a robot's frame: positions relative to the
# shoulder, scaled by the ratio of arm lengths, placed at the robot's shoulder.

# %%
from nlo_lab.human import map_to_robot
from nlo_lab.robot import load_robot

mapped = map_to_robot(demo, load_robot("nao"))     # (T, 2, 3, 3): side, (shoulder, elbow, wrist), xyz [m]
print(mapped.shape, "left wrist at frame 0 in NAO's frame:", mapped[0, 0, 2].round(3))

# %% [markdown]
# ## Exercises
#
# 1. Which handshapes differ only in the thumb? Find them from `HANDSHAPES`.
# 2. Plot the left and right wrist heights of a two-handed sign; is the motion symmetric?
# 3. In the real recording, in which frames is the left hand missing? What will the objective do with those frames?
# 4. Compare `node_features` of a corpus frame and of a real frame: which features are on a similar scale?
# 5. Why does the mapping to a robot use ratios of arm lengths rather than raw positions?
