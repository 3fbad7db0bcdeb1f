# %% [markdown]
# # 05. Neural initialisation
#
# ## Learning goals
#
# - Know the four initialisations of latent optimisation: the **encoder** `f_phi` (neural initialisation),
#   **random** `z0 ~ N(0, 1)`, **train-stats** (mean and spread of the training latents) and **zeros**.
# - Measure the ablation initialisation × iteration budget with convergence curves.
# - Use the interactive panel: loss weights, initialisation, budget, robot and frame, re-optimised live.

# %%
from nlo_lab.lab import TEST_MODE, budget, setup

setup()

# %%
import numpy as np

from nlo_lab.corpus import corpus_clip, corpus_names
from nlo_lab.model import encoder_input, load_pretrained
from nlo_lab.objective import targets_from_demonstration
from nlo_lab.robot import load_robot

robot = load_robot("yumi")
model = load_pretrained(robot)
demo = corpus_clip(corpus_names("test")[0])
demo = demo.slice(0, budget(len(demo), 12))            # fewer frames in test mode
targets = targets_from_demonstration(demo, dtype=robot.lower_limits.dtype)  # what the objective compares
features = encoder_input(demo)                                               # what the encoder reads
print(f"{demo.name}: {len(demo)} frames, unseen sign combinations (test split)")

# %% [markdown]
# ## The ablation
#
# Every frame of the clip, every initialisation, the same budget; the curves show the mean loss over
# frames after each step. Budget 0 is the start itself: for the encoder, that is the encoder's own answer.

# %%
from nlo_lab.inference import INITS, OptimizeSettings, optimize_latent
from nlo_lab.viz import plot_convergence

ITERS = budget(100, 10)
runs = {init: optimize_latent(model, robot, targets, OptimizeSettings(init=init, iterations=ITERS, patience=ITERS), encoder_input=features)
        for init in INITS}
plot_convergence({init: r.history for init, r in runs.items()}, title=f"{len(demo)} frames, mean loss");

# %%
BUDGETS = budget([0, 10, 30, 100], [0, 5])
print(f"{'init':12s}" + "".join(f"{b:>10d}" for b in BUDGETS) + "   (mean loss after N steps)")
for init, r in runs.items():
    h = np.asarray(r.history)
    print(f"{init:12s}" + "".join(f"{h[min(b, len(h) - 1)]:10.2f}" for b in BUDGETS))

# %% [markdown]
# The tracking error (the discrete Fréchet distance of the wrist and elbow paths, mapped into the robot's
# frame: `nlo_lab.metrics.tracking_errors`) measures the same runs in metres. Does it rank them as the loss does?

# %%
from IPython.display import Markdown

from nlo_lab.metrics import tracking_errors

frechet = {}
for init, r in runs.items():
    e = tracking_errors(demo, robot, r.q)
    frechet[init] = e["frechet_m"]
    print(f"{init:12s} Fréchet {e['frechet_m'] * 100:6.2f} cm   (wrist {e['frechet_wrist_m'] * 100:.2f}, elbow {e['frechet_elbow_m'] * 100:.2f})")
by_loss = sorted(runs, key=lambda init: runs[init].history[-1])
by_frechet = sorted(frechet, key=frechet.get)
Markdown(f"Ranked by the final loss: {' < '.join(by_loss)}; by the Fréchet distance: {' < '.join(by_frechet)}. "
         + ("The two agree." if by_loss == by_frechet else
            "They differ: the objective is not the metric (it also weighs orientation, fingers and collision)."))

# %% [markdown]
# ## The interactive panel
#
# - a **weight** slider re-optimises the current frame, warm-started from its latent (≤ 30 steps);
# - **init** and **iterations** restart the current frame from that initialisation with that budget (the
#   earlier curves stay, faded, for comparison);
# - **frame** (or play) moves along the clip, re-optimising each frame it reaches;
# - **robot** switches robot (and loads its shipped model); the button optimises the whole sequence.
#
# The same panel works headless: `panel.controls["init"].value = "random"` does what the dropdown does.

# %%
from nlo_lab.lab import RetargetPanel

panel = RetargetPanel(demo, "yumi", model=model, iterations=ITERS)
panel

# %%
for init in INITS:                         # what the dropdown does, from code
    panel.controls["init"].value = init
    print(f"{init:12s} {panel.history[0]:9.2f} -> {min(panel.history):7.2f} in {panel.last_seconds * 1000:5.0f} ms")

# %% [markdown]
# ## Exercises
#
# 1. Predict, then check: at budget 0, which initialisation is best? At budget 100?
# 2. Lower the collision weight in the panel to 0.1 and scrub through the frames: where do the arms collide?
# 3. Switch the panel to NAO: which initialisation gains most from optimisation there?
# 4. Repeat the ablation on a clip of the *train* split. Does the encoder's advantage grow or shrink? Why?
# 5. How many steps does random initialisation need to reach the encoder's loss at 10 steps?
