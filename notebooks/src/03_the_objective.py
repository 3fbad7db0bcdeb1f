# %% [markdown]
# # 03. The objective
#
# ## Learning goals
#
# - Know the five terms of the retargeting objective `L(D, K(q))`: end effector, wrist orientation,
#   elbow→wrist direction, finger directions, self-collision, and what each one measures.
# - Read each term's equation next to the code that computes it.
# - See how the loss weights trade the terms against each other.
# - Optimise the joint angles of one frame directly (the joint-space baseline) and see how it fails:
#   local minima that depend on the start, and joint limits that need clamping or a penalty.

# %%
from nlo_lab.lab import TEST_MODE, budget, setup

setup()

# %%
import matplotlib.pyplot as plt
import torch

from nlo_lab.corpus import corpus_clip, corpus_names
from nlo_lab.objective import LossWeights, objective, targets_from_demonstration
from nlo_lab.robot import load_robot

robot = load_robot("yumi")
demo = corpus_clip(corpus_names("test")[0])
targets = targets_from_demonstration(demo, dtype=robot.lower_limits.dtype)
t = len(demo) // 2
one = targets.index(slice(t, t + 1))            # the targets of one frame
print(f"{demo.name}, frame {t}")

# %% [markdown]
# ## Each term on one frame
#
# At the robot's neutral pose, before any optimisation. `objective` returns the weighted total and the
# *unweighted* terms; the weights (the paper's by default) decide how much each one counts.

# %%
from nlo_lab.viz import plot_loss_terms

q0 = robot.neutral_q[None]
total, terms = objective(robot, q0, one)
fig, axes = plt.subplots(1, 2, figsize=(10, 3))
plot_loss_terms(terms, ax=axes[0], title="unweighted terms")
plot_loss_terms(terms, ax=axes[1], weights=LossWeights().as_dict(), title=f"weighted (total {float(total):.1f})");

# %% [markdown]
# ## Each term as code
#
# Every term is one small function in `nlo_lab.objective.terms`: its docstring holds the paper's equation
# (a hat marks the human side), its body computes it, and `needs` names the robot points it reads. These
# functions are what `objective` runs; the robot's points come from one forward-kinematics call.

# %%
import inspect

from IPython.display import Markdown, display

from nlo_lab.objective import terms as term_functions

for fn in (term_functions.end_effector_loss, term_functions.orientation_loss, term_functions.elbow_loss,
           term_functions.finger_loss, term_functions.collision_loss):
    display(Markdown(f"**`{fn.__name__}`** reads the robot's {', '.join(fn.needs)}\n```python\n{inspect.getsource(fn)}```"))

# %% [markdown]
# `Objective` assembles them: `terms @ weights`, one weight per term; that is what `objective` runs. The
# optimiser asks for a faster form for a few frames, the same terms in numpy with a written-out gradient
# (`fused=True`), and the numbers stay the same:

# %%
from nlo_lab.objective import Objective

print(inspect.getsource(Objective.terms))
fused_total, _ = objective(robot, q0, one, fused=True)
print(f"term functions {float(total):.6f}, numpy terms {float(fused_total):.6f}")

# %% [markdown]
# ## Joint-space optimisation of one frame
#
# The obvious approach: gradient descent (Adam) on the angles `q` themselves. Joint limits are kept by
# clamping after each step (projected gradient). It starts from the robot's collision-free neutral pose
# (`JointOptimizeSettings(init="neutral")`, the default).

# %%
from nlo_lab.inference import JointOptimizeSettings, optimize_joints
from nlo_lab.viz import plot_convergence

ITERS = budget(300, 30)
res = optimize_joints(robot, one, JointOptimizeSettings(iterations=ITERS, patience=ITERS))
print(f"loss {res.history[0]:.1f} -> {res.history[-1]:.2f} in {res.iterations} steps, {res.seconds * 1000:.0f} ms")
plot_convergence({"joint space, from the neutral pose": res.history});

# %%
from nlo_lab.lab import show_view

show_view(robot, res.q[0], demo=demo.slice(t, t + 1))   # the robot beside the human's frame

# %% [markdown]
# ## Weight sliders
#
# Move a weight and release it: the sliders build `LossWeights`, and the frame is optimised again in joint
# space with them (the same start and budget as above). The 3-D view shows the pose these weights give,
# beside the human; the bars show the weighted terms at that pose, the line below each term's share of the
# total. Lower `finger` to 0.1, or raise `elbow` to 10,000, and watch the hands and the arms.

# %%
from nlo_lab.lab import WeightsPanel

WeightsPanel(robot, one, demo.slice(t, t + 1), iterations=budget(100, 20))

# %% [markdown]
# ### Local minima
#
# The objective is not convex in `q`: from different random starts inside the limits, the same frame can end
# at different losses, so the result depends on where we start.

# %%
gen = torch.Generator().manual_seed(0)
lo, hi = robot.lower_limits, robot.upper_limits
histories = {}
for seed in range(budget(6, 3)):
    q_start = lo + (hi - lo) * torch.rand(1, robot.n_joints, generator=gen, dtype=lo.dtype)
    r = optimize_joints(robot, one, JointOptimizeSettings(iterations=ITERS, patience=ITERS), q0=q_start)
    histories[f"start {seed}: {r.history[-1]:.2f}"] = r.history
plot_convergence(histories, title="joint space from random starts")
plt.show()
final = sorted(h[-1] for h in histories.values())
Markdown(f"Here the {len(final)} starts ended between **{final[0]:.2f}** and **{final[-1]:.2f}** "
         f"({final[-1] / final[0]:.1f}× the best), against {res.history[-1]:.2f} from the neutral pose.")

# %% [markdown]
# ### Limits
#
# Without clamping, limits can only be encouraged by a penalty. A weak penalty can let the optimiser leave
# the limits to lower the tracking terms, and the result is then not a pose the robot can take.

# %%
from nlo_lab.metrics import limit_violations

outside = {}
for limits, penalty in (("clamp", 1e4), ("penalty", 1e4), ("penalty", 1.0)):
    r = optimize_joints(robot, one, JointOptimizeSettings(iterations=ITERS, patience=ITERS, limits=limits, penalty=penalty))
    outside[(limits, penalty)] = limit_violations(robot, r.q)
    print(f"{limits:8s} penalty {penalty:8.0f}: loss {r.history[-1]:8.2f}, joints outside their limits: {outside[(limits, penalty)]}")
weak = outside[("penalty", 1.0)]
Markdown(f"Clamping leaves {outside[('clamp', 1e4)]} joints outside their limits; the weak penalty leaves **{weak}** "
         + ("outside: a pose the robot cannot take." if weak else "outside on this frame with this budget: try more iterations."))

# %% [markdown]
# ## Exercises
#
# 1. Set the collision weight to 0.1 and re-run the joint-space optimisation: does the result self-collide?
#    (`nlo_lab.metrics.self_collision_frames(robot, res.q)`)
# 2. Which term dominates the total at the neutral pose? After optimisation?
# 3. Optimise 20 random starts and histogram the final losses. How many distinct minima do you see?
# 4. Optimise every frame of the clip in joint space (`targets` instead of `one`) and plot one joint over time. Is it smooth?
# 5. Try NAO (no fingers): which term is always zero, and why?
