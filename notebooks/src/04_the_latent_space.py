# %% [markdown]
# # 04. The latent space
#
# ## Learning goals
#
# - See the decoder `f_psi: z -> q` as a hard constraint: a `tanh` and a linear remap put every angle inside
#   its limits, for *any* latent code `z`.
# - Understand the auto-decoder idea: with the decoder frozen, retargeting one frame is an optimisation over
#   `z` instead of over `q`.
# - Run latent optimisation from random starts and compare it with joint-space optimisation.

# %%
from nlo_lab.lab import TEST_MODE, budget, setup

setup()

# %%
import matplotlib.pyplot as plt
import numpy as np
import torch

from nlo_lab.model import load_pretrained
from nlo_lab.robot import load_robot

robot = load_robot("yumi")
model = load_pretrained(robot)           # the shipped checkpoint: no training needed
print("latent of one frame:", model.latent_shape, "(one k-vector per robot-graph node)")

# %% [markdown]
# ## The decoder keeps every angle inside its limits
#
# Decode many random latents, even far from the training distribution (σ = 3), and look where the angles
# fall between their lower (0) and upper (1) limits.

# %%
N = budget(4000, 400)
z = 3.0 * torch.randn(N, *model.latent_shape, dtype=robot.lower_limits.dtype)
with torch.no_grad():
    q = model.decode(z)                                   # (N, n) [rad]
lo, hi = robot.lower_limits, robot.upper_limits
u = ((q - lo) / (hi - lo)).numpy()                         # position inside the limits
plt.figure(figsize=(6, 3))
plt.hist(u.ravel(), bins=50); plt.xlabel("(q - lower) / (upper - lower)"); plt.ylabel("count")
print(f"angles outside the limits: {int(((q < lo) | (q > hi)).sum())} of {q.numel()}")

# %% [markdown]
# ## The auto-decoder: optimise `z`, not `q`
#
# At inference the decoder is frozen and only `z` moves: `z* = argmin_z L(D, K(f_psi(z))) + ||z||²/σ²`.
# Every step stays feasible (the decoder's limits, by construction: the histogram above), and the decoder
# has learnt which poses are plausible. Whether that makes the optimiser's job easier depends on where it
# starts: the next section starts it at random.

# %%
from nlo_lab.corpus import corpus_clip, corpus_names
from nlo_lab.objective import targets_from_demonstration

demo = corpus_clip(corpus_names("test")[1])
targets = targets_from_demonstration(demo, dtype=robot.lower_limits.dtype)
t = len(demo) // 2
one = targets.index(slice(t, t + 1))

# %% [markdown]
# ## Latent optimisation from random starts
#
# The same frame from several random latents `z0 ~ N(0, 1)`, against joint-space optimisation from as
# many random starts and the same number of steps.

# %%
from nlo_lab.inference import JointOptimizeSettings, OptimizeSettings, optimize_joints, optimize_latent
from nlo_lab.viz import plot_convergence

ITERS, SEEDS = budget(150, 20), budget(6, 3)
latent, joints = {}, {}
gen = torch.Generator().manual_seed(0)
for seed in range(SEEDS):
    r = optimize_latent(model, robot, one, OptimizeSettings(init="random", seed=seed, iterations=ITERS, patience=ITERS))
    latent[f"z0 seed {seed}"] = r.history
    q0 = lo + (hi - lo) * torch.rand(1, robot.n_joints, generator=gen, dtype=lo.dtype)
    joints[f"q0 seed {seed}"] = optimize_joints(robot, one, JointOptimizeSettings(iterations=ITERS, patience=ITERS), q0=q0).history
fig, axes = plt.subplots(1, 2, figsize=(11, 3.5), sharey=True)
plot_convergence(latent, ax=axes[0], title="latent optimisation (random z0)")
plot_convergence(joints, ax=axes[1], title="joint-space optimisation (random q0)");

# %%
final_latent = [h[-1] for h in latent.values()]
final_joints = [h[-1] for h in joints.values()]
print(f"final loss, latent: {np.mean(final_latent):.2f} ± {np.std(final_latent):.2f}")
print(f"final loss, joints: {np.mean(final_joints):.2f} ± {np.std(final_joints):.2f}")

# %% [markdown]
# For contrast, the same frame and budget from the encoder's guess (the method's start, notebook 05):

# %%
from IPython.display import Markdown

from nlo_lab.model import encoder_input

guided = optimize_latent(model, robot, one, OptimizeSettings(init="encoder", iterations=ITERS, patience=ITERS),
                         encoder_input=encoder_input(demo.slice(t, t + 1)))
worse = np.mean(final_latent) > np.mean(final_joints)
Markdown(
    f"On this frame, from {SEEDS} random starts each, latent optimisation ended at a mean loss of **{np.mean(final_latent):.2f}** "
    f"(best {min(final_latent):.2f}) and joint-space optimisation at **{np.mean(final_joints):.2f}** (best {min(final_joints):.2f}): "
    + ("from random starts the latent space did **worse**. A random `z0` decodes to an arbitrary pose, and where the decoder's "
       "`tanh` saturates, steps in `z` barely move the angles. " if worse else
       "from random starts the latent space did **better** here. ")
    + f"From the encoder's guess the same budget reaches **{guided.history[-1]:.2f}** "
    + ("(below every random start of either kind): what the latent space offers pays off with a good start."
       if guided.history[-1] < min(final_latent + final_joints) else "(not below every random start on this frame).")
)

# %% [markdown]
# The best latent solution, beside the human:

# %%
from nlo_lab.lab import show_view

best = optimize_latent(model, robot, one, OptimizeSettings(init="random", seed=int(np.argmin(final_latent)), iterations=ITERS))
show_view(robot, best.q, demo=demo.slice(t, t + 1))

# %% [markdown]
# ## Exercises
#
# 1. Decode latents with σ = 10. Where do the angles pile up, and why (think of `tanh`)?
# 2. Set the latent weight of `LossWeights` to 0 and to 10: how do the final loss and `||z||` change?
# 3. Start latent optimisation from `init="zeros"`: is it better or worse than random starts on this frame?
# 4. Count the joint-space runs that end worse than the worst latent run. What does that say about local minima?
# 5. Time both optimisers (`result.seconds`) for the same number of steps. Which step is more expensive, and why?
