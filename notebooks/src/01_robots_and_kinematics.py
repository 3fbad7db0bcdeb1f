# %% [markdown]
# # 01. Robots and forward kinematics
#
# ## Learning goals
#
# - Load the three robots of the lab (ABB YuMi with two Inspire hands, NAO, Pepper) and read their joint tables.
# - Move a robot joint by joint with sliders and watch it in the 3-D viewer.
# - Compute forward kinematics (FK): joint angles `q` [rad] → the pose `T_world_link` (4×4) of every link, batched.
# - Check our FK against the field's reference, pytorch-kinematics, and see why ours is faster.
# - Read the robot structure graph that the decoder of the method is built on.

# %%
from nlo_lab.lab import TEST_MODE, budget, setup

setup()

# %% [markdown]
# ## The three robots
#
# A robot is a URDF (links, joints, limits) plus a small spec file that names the roles of links
# (shoulder, elbow, wrist, finger base and tip) and the capsules used for self-collision.
# `joint_names` fixes the order of the angle vector `q`.

# %%
from nlo_lab.robot import load_robot

robots = {name: load_robot(name) for name in ("yumi", "nao", "pepper")}
for name, robot in robots.items():
    print(f"{name:7s} {robot.n_joints:2d} actuated joints, fingers: {robot.has_fingers}")

# %%
from nlo_lab.lab import joint_table

joint_table(robots["nao"])

# %%
from nlo_lab.lab import show_robot

yumi = robots["yumi"]
show_robot(yumi)  # the neutral pose, in a 3-D view of its own: drag to turn, scroll to zoom

# %% [markdown]
# ## Joint sliders
#
# Each slider moves one joint inside its limits; the 3-D view and the position of the chosen link
# (computed by FK) follow.

# %%
from nlo_lab.lab import JointPanel

JointPanel(robots["nao"])

# %% [markdown]
# The same with `ipywidgets.interact`, for one joint: the height of NAO's left wrist as its first joint moves.
# `fixed(...)` hands the robot, the joint and the link to the function as arguments: a slider moved later
# still uses these, whatever later cells assign to global names such as `wrist`.

# %%
from ipywidgets import fixed, interact

nao = robots["nao"]
lo, hi = float(nao.lower_limits[0]), float(nao.upper_limits[0])

@interact(angle=(lo, hi, 0.01), robot=fixed(nao), j=fixed(0), link=fixed(nao.arm("left").wrist))
def wrist_height(angle=0.0, robot=None, j=0, link=""):
    q = robot.neutral_q.clone()
    q[j] = angle
    z = float(robot.forward_kinematics(q[None])[link][0, 2, 3])
    print(f"{robot.joint_names[j]} = {angle:+.2f} rad -> {link} height {z:+.3f} m")

# %% [markdown]
# ## Forward kinematics
#
# `robot.forward_kinematics(q)` takes a batch `q (B, n)` and returns `{link: T_world_link (B, 4, 4)}`
# for every link. The translation column is the link's position [m] in the robot frame
# (origin between the shoulders, X forward, Y left, Z up).

# %%
import torch

q = yumi.neutral_q[None]                     # (1, n)
poses = yumi.forward_kinematics(q)           # {link: (1, 4, 4)}
wrist = yumi.arm("left").wrist
print(wrist)
print(poses[wrist][0].numpy().round(3))

# %% [markdown]
# ### FK as code
#
# Every link hangs from its parent by a joint: a constant origin transform from the URDF, then the joint's
# own motion (a rotation by `q` about its axis, or a translation along it):
#
# $$T_{world,link} = T_{world,parent} \cdot T_{origin} \cdot T_{joint}(q)$$
#
# `body_poses` below computes every local transform `T_origin · T_joint(q)` of the tree in one matrix product
# (a rotation is linear in sin q and cos q), then composes the chain. `_compose_by_levels` is the equation
# as written: one tree level after the other, each frame its parent's frame times its local transform.

# %%
import inspect

from nlo_lab.robot import KinematicTree

print(inspect.getsource(KinematicTree.body_poses))
print(inspect.getsource(KinematicTree._compose_by_levels))

# %% [markdown]
# That is what `forward_kinematics` runs. The optimiser asks for a faster composition at small batches
# (pointer jumping, further below: `body_poses(q, compose="jumps")`); the poses agree to float32 rounding
# (the two compositions multiply the same matrices in another order).

# %%
jumps = yumi.tree.body_poses(q, compose="jumps")
print(f"largest difference to pointer jumping: {float((jumps - yumi.tree.body_poses(q)).abs().max()):.1e}")

# %% [markdown]
# FK is batched and differentiable: thousands of random poses inside the limits at once give a picture of
# the workspace of the left wrist.

# %%
import matplotlib.pyplot as plt

B = budget(5000, 500)
lo, hi = yumi.lower_limits, yumi.upper_limits
q = lo + (hi - lo) * torch.rand(B, yumi.n_joints, dtype=lo.dtype)
p = yumi.forward_kinematics(q)[wrist][:, :3, 3].numpy()    # (B, 3) [m]
fig, axes = plt.subplots(1, 2, figsize=(8, 3.5))
axes[0].scatter(p[:, 0], p[:, 1], s=1); axes[0].set(xlabel="x [m]", ylabel="y [m]", title="top view")
axes[1].scatter(p[:, 1], p[:, 2], s=1); axes[1].set(xlabel="y [m]", ylabel="z [m]", title="front view")
fig.tight_layout()

# %% [markdown]
# ### Our FK beside pytorch-kinematics
#
# [pytorch-kinematics](https://github.com/UM-ARM-Lab/pytorch_kinematics) is the library robotics users
# reach for to get differentiable FK from a URDF. `PKChain(robot)` builds its chain from the same URDF
# and feeds it our angle vector: pytorch-kinematics does not read `<mimic>`, so the coupled finger joints
# of the Inspire hands are expanded first (`ref.angles(q)`: 26 actuated angles → 38 joints). Both give the
# same poses, to the float32 rounding of the URDF's numbers that pytorch-kinematics does when it reads them.

# %%
from nlo_lab.robot.pk_chain import PKChain

ref = PKChain(yumi)                              # ref.chain is the pytorch_kinematics.Chain
print(f"{len(ref.joint_names)} joints in the chain, {yumi.n_joints} actuated angles")
ours, theirs = yumi.forward_kinematics(q), ref.forward_kinematics(q)
print(f"{len(theirs)} links, largest difference {max(float((ours[k] - theirs[k]).abs().max()) for k in theirs):.1e}")

# %% [markdown]
# Same numbers, different cost. pytorch-kinematics walks the tree in a Python loop, one link after the
# other, with a few 4×4 products and some bookkeeping per link (55 links on YuMi). Ours does the walk once
# when the robot is loaded and keeps constants: every joint's local transform comes out of **one** matrix
# product (Rodrigues' formula is linear in sin θ and cos θ), and the chain is composed in one batched
# product per tree level over all links at once (or, asked for, by pointer jumping in ⌈log₂(depth + 1)⌉).
# At batch 1 nearly all the time is the per-operation overhead of torch, so fewer operations win; at large
# batches the arithmetic counts too. How much faster depends on the batch and on the machine: the cell
# below measures it here and now.

# %%
import time

from IPython.display import Markdown

RUNS = budget(30, 5)


def median_ms(fn, *args):
    times = []
    for _ in range(RUNS):
        t0 = time.perf_counter(); fn(*args); times.append(time.perf_counter() - t0)
    return 1e3 * sorted(times)[len(times) // 2]

ratio = {}
with torch.no_grad():
    for B in (1, 256):
        qb = lo + (hi - lo) * torch.rand(B, yumi.n_joints, dtype=lo.dtype)
        t_ours, t_pk = median_ms(yumi.forward_kinematics, qb), median_ms(ref.forward_kinematics, qb)
        ratio[B] = t_pk / t_ours
        print(f"batch {B:3d}: ours {t_ours:6.2f} ms, pytorch-kinematics {t_pk:6.2f} ms, ratio {ratio[B]:5.1f}")
Markdown(f"Measured just now: our FK is **{ratio[1]:.1f}×** as fast as pytorch-kinematics at batch 1 and "
         f"**{ratio[256]:.1f}×** at batch 256 (medians of {RUNS} runs each), so here the gap is "
         f"{'smaller' if ratio[256] < ratio[1] else 'larger'} at the large batch.")

# %% [markdown]
# Self-collision is measured between capsules attached to links: `capsule_distances` gives the surface
# distance of every pair that may collide (< 0: penetration). The neutral pose is collision-free.

# %%
d = yumi.capsule_distances(yumi.forward_kinematics(yumi.neutral_q[None]))   # (1, P) [m]
print(f"{d.shape[1]} capsule pairs, closest {float(d.min()):.3f} m apart")
print(f"random poses with a penetrating pair: {float((yumi.capsule_distances(yumi.forward_kinematics(q)).min(1).values < 0).float().mean()):.0%}")

# %% [markdown]
# ## The robot structure graph
#
# Nodes are the actuated joints, edges go from a joint to the next one down the chain (edge features:
# the joint origin, xyz + rpy). The decoder of the method is a graph network over this graph.
#
# The first joint of each arm has no actuated joint above it. Instead of a root node without an angle,
# the graph joins the two arms' first joints by one edge in each direction (the dashed bracket), so the
# arms exchange messages (the collision term couples them). The grey *torso* square is a drawing aid
# only: the graph has no such node.

# %%
from nlo_lab.lab import plot_graph

for robot, title in ((yumi, "YuMi with two Inspire hands"), (nao, "NAO")):
    plot_graph(robot.graph, robot.joint_names, title=f"{title}: {robot.graph.num_nodes} nodes, {robot.graph.num_edges} edges",
               base="torso")

# %% [markdown]
# ## Exercises
#
# 1. Find the joint of NAO that moves the left wrist highest when set to its upper limit. Predict first, then check with the sliders.
# 2. Compute the distance between YuMi's two wrists at the neutral pose with `forward_kinematics`.
# 3. Plot Pepper's left-wrist workspace as above. How does it compare with NAO's (scale, shape)?
# 4. What fraction of uniformly random YuMi poses self-collides? Why does that matter for an optimiser that samples poses?
# 5. Count the nodes of each arm and each hand in `yumi.graph` from `node_type`.
# 6. Time both FKs at batch 1, 16, 64, 256 and 1024 and plot the ratio. Where does pytorch-kinematics catch up, and why there?
