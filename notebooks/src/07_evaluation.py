# %% [markdown]
# # 07. Evaluation against the baselines
#
# ## Learning goals
#
# - Run the method and five baselines through **one interface** (`nlo_lab.evaluation`): encoder +
#   latent optimisation, the encoder alone ('Init'), latent optimisation from random starts,
#   joint-space optimisation, a supervised network ('NN') and wrist-only inverse kinematics.
# - Read a table like the paper's Table I: Fréchet distance per test sequence, `*` for self-collision.
# - Compare smoothness (velocity and acceleration errors) and wall time, and see where each method fails.
# - Know the contract of `nlo-lab evaluate --json`.

# %%
from nlo_lab.lab import TEST_MODE, budget, setup

setup()

# %% [markdown]
# ## The test sequences
#
# The test split holds two scenarios whose sign combinations never occur in training, so every method
# here sees unseen motions. In test mode we keep two short clips.

# %%
from nlo_lab.corpus import corpus_clip, corpus_names
from nlo_lab.model import load_pretrained
from nlo_lab.robot import load_robot

robot = load_robot("yumi")
model = load_pretrained(robot)
names = corpus_names("test")[: budget(6, 2)]
demos = [corpus_clip(n) for n in names]
demos = [d.slice(0, budget(len(d), 25)) for d in demos]
print([(d.name, len(d)) for d in demos])

# %% [markdown]
# ## One interface, six methods
#
# Every method is `method(robot, demo, settings) -> MethodResult(angles (T, n), seconds, ...)`.
# `BaselineSettings` holds the shared budget: the latent methods and joint-space optimisation get the
# same number of steps (`iterations`): Adam steps on the angles for joint space; for the latent methods the
# pipeline's step rule (Rprop on a whole recording in robot-ready mode, the paper's Adam in paper mode). The supervised network first needs labels: joint-space optimisation of
# training frames (the paper's NN learns from an optimiser's output); it is trained once and cached.

# %%
from nlo_lab.evaluation import BaselineSettings, run_method
from nlo_lab.training import SupervisedSettings, supervised_network

settings = BaselineSettings(
    iterations=budget(100, 10),
    supervised=SupervisedSettings(frame_stride=budget(4, 64), label_iterations=budget(150, 20), epochs=budget(60, 5)),
)
network = supervised_network(robot, settings.supervised)
print(f"nn_supervised: {network.info['samples']} labelled frames, labels {network.info['label_seconds']:.1f} s, training {network.info['train_seconds']:.1f} s")

# %%
r = run_method("ik", robot, demos[0], settings)
print(r.method, r.angles.shape, f"{r.seconds:.2f} s")

# %% [markdown]
# ## Table I on our data
#
# `evaluate` runs every method on every sequence and scores it with the metric of `docs/DESIGN.md`: the discrete
# Fréchet distance of wrist and elbow paths after mapping the human into the robot's frame (mean of
# the two), plus self-collision frames and joint-limit violations.

# %%
from nlo_lab.evaluation import evaluate, format_table

ev = evaluate(robot, demos, settings, model=model, network=network, progress=False)
print(format_table(ev))

# %% [markdown]
# Things to look for. IK is asked to track the wrists only: not the elbows, the hand orientation or
# collisions. The supervised network needs no optimisation at run time, and is only as good as its labels
# and its generalisation. Random latent starts get the same budget as the encoder's. What this run shows:

# %%
from IPython.display import Markdown

the_method, n = "latent_encoder", len(ev.sequences)
def seen(m):
    return (f"wrists {ev.mean(m, 'frechet_wrist_m'):.3f} m, elbows {ev.mean(m, 'frechet_elbow_m'):.3f} m, "
            f"self-collision in {ev.collision_sequences(m)} of {n} sequences, {ev.total(m, 'seconds'):.2f} s")
Markdown("\n".join(f"- **{m}**: {seen(m)}" + (" (the method)" if m == the_method else "") for m in ev.methods))

# %% [markdown]
# ## Similarity against time
#
# The paper's comparison figure: the lower left corner is best (similar motion, little time).

# %%
import matplotlib.pyplot as plt

fig, ax = plt.subplots(figsize=(6, 3.5))
for m in ev.methods:
    ax.scatter(ev.total(m, "seconds"), ev.mean(m), marker="*" if ev.collision_sequences(m) else "o")
    ax.annotate(m, (ev.total(m, "seconds"), ev.mean(m)), fontsize=8, xytext=(3, 3), textcoords="offset points")
ax.set_xscale("log"); ax.set_xlabel("wall time [s]"); ax.set_ylabel("mean Fréchet distance [m]");

# %% [markdown]
# ## Smoothness: velocity and acceleration errors
#
# The paper optimises every frame on its own: it has "no mechanism to ensure smoothness". Our objective
# adds one, the smoothness term (not in the paper): each joint's speed between consecutive frames in units
# of its velocity limit, squared, weighted by `LossWeights.smooth`. The methods that optimise a whole
# sequence (the latent methods and joint space) use it, unless the evaluation is in the paper's mode
# (`BaselineSettings(mode="paper")`: no smoothness term); the encoder alone, the supervised network and IK
# map every frame on its own. The errors below are differences of finite-difference derivatives of the
# wrist and elbow paths, human (mapped) against robot: how closely each method follows the human's own
# speed and acceleration.

# %%
from nlo_lab.inference import smoothness_term
from nlo_lab.objective import LossWeights, targets_from_demonstration

sequence = targets_from_demonstration(demos[0], dtype=robot.lower_limits.dtype)
weights = settings.loss_weights  # what this evaluation optimises (BaselineSettings.mode)
print(f"smoothness weight: {weights.smooth:g} in this {settings.mode} evaluation (LossWeights().smooth = {LossWeights().smooth:g}); "
      f"a smoothness term over {len(sequence)} frames at {sequence.fps:g} fps: {smoothness_term(robot, sequence, weights) is not None}")
fig, axes = plt.subplots(1, 2, figsize=(8, 3))
for ax, key, unit in zip(axes, ("velocity_error", "acceleration_error"), ("m/s", "m/s²"), strict=True):
    ax.bar(range(len(ev.methods)), [ev.mean(m, key) for m in ev.methods])
    ax.set_xticks(range(len(ev.methods)), ev.methods, rotation=45, ha="right", fontsize=7)
    ax.set_title(f"{key.replace('_', ' ')} [{unit}]")
fig.tight_layout()

# %% [markdown]
# ## Wrist paths, human against robot
#
# The human wrist mapped into the robot frame (`map_to_robot`), against the robot's wrist from forward
# kinematics, for the method and for IK.

# %%
import torch

from nlo_lab.evaluation import wrist_positions
from nlo_lab.human import map_to_robot

demo = demos[0]
human = map_to_robot(demo, robot)[:, :, 2]                      # (T, 2, 3) [m]
fig, axes = plt.subplots(1, 3, figsize=(9, 2.8), sharex=True)
for method in ("latent_encoder", "ik"):
    q = torch.as_tensor(run_method(method, robot, demo, settings, model=model).angles, dtype=robot.lower_limits.dtype)
    w = wrist_positions(robot, q).detach().numpy()
    for c, ax in enumerate(axes):
        ax.plot(w[:, 1, c], label=method)
for c, ax in enumerate(axes):
    ax.plot(human[:, 1, c], "k--", label="human (mapped)"); ax.set_title(f"right wrist {'xyz'[c]} [m]")
axes[0].legend(fontsize=7); axes[1].set_xlabel("frame");

# %% [markdown]
# ## The command line
#
# `nlo-lab evaluate --robot yumi --json` runs the same evaluation on the whole test split and prints, as
# its last line, one JSON object with exactly these keys per method (a contract that scripts rely on):

# %%
import json

from nlo_lab.evaluation import to_json

obj = to_json(ev)
print(sorted(obj["methods"]), sorted(obj["methods"]["latent_encoder"]))
print(json.dumps(obj["methods"]["latent_encoder"], indent=1)[:400])

# %% [markdown]
# ### Joint speeds: what `velocity_violations` counts
#
# `velocity_violations` (a row of the table, a key of the JSON) counts the (frame pair, joint) entries in
# which a joint turns faster than its velocity limit, on the time base the method's output plays at.
# Retiming keeps the angles and plays a frame later wherever a joint would be too fast
# (`nlo_lab.inference.retime_times`), as `retarget()` and `nlo-lab retarget` do. In robot-ready mode
# (`BaselineSettings.mode`, the default) the latent methods retime their output too; the other methods'
# frames play at the recording's rate. On the first clip, before and after retiming:

# %%
import numpy as np

from nlo_lab.inference import retime_times
from nlo_lab.metrics import max_joint_speed_ratio, velocity_violations

result = run_method(the_method, robot, demo, settings, model=model)
q = result.angles                                                          # (T, n) [rad]
times = retime_times(q, demo.fps, robot.velocity_limits.double().numpy())  # (T,) [s], what retarget() plays
before, after = velocity_violations(robot, q, fps=demo.fps), velocity_violations(robot, q, times=times)
Markdown(f"{the_method} on `{demo.name}` ({len(q)} frames at {demo.fps:g} fps), its frames played at the recording's rate: "
         f"**{before}** of its {(len(q) - 1) * robot.n_joints} (frame pair, joint) entries are over the limit, the fastest joint at "
         f"{max_joint_speed_ratio(robot, q, fps=demo.fps):.2f}× its limit. Retimed, the clip lasts "
         f"{(times[-1] + 1 / demo.fps) * demo.fps / len(q):.2f}× as long, with **{after}** entries over the limit (fastest "
         f"{max_joint_speed_ratio(robot, q, times=times):.2f}×). In this {settings.mode} evaluation the method's output "
         + ("is retimed" if result.times is not None else "is not retimed")
         + f": the table counts {int(ev.total(the_method, 'velocity_violations'))} entries over its {n} sequences.")

# %% [markdown]
# `nlo-lab evaluate --robot yumi` scores every sequence of the test split with the full budgets (add
# `--json` for the object above, `--limit N` for the first N sequences).
#
# ## Exercises
#
# 1. Give every iterating method 10 times fewer steps (`iterations=10`). Predict which ranking changes
#    first, then rerun the table.
# 2. Set `random_sigma=0.1` and then `2.0` in `BaselineSettings`. Which one is closer to the encoder after
#    the same budget, and why does a start far from the prior (`||z||²`) cost steps?
# 3. Lower `ik_damping` to 0.001 and raise it to 0.5. Predict what happens to the wrist error and to the
#    acceleration error (jumps between frames) before running.
# 4. Train the supervised network with `label_iterations=20` instead of 150. How much worse can the NN be
#    than its labels' own optimiser, and why (the paper's "cumulative error")?
# 5. Evaluate NAO or Pepper instead of YuMi. Which baseline gains most from a robot with human-like
#    proportions?
