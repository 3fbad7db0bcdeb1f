# %% [markdown]
# # 12. Handshapes: fingers that sign
#
# ## Learning goals
#
# - Measure a handshape the way `benchmarks/hands.py` does: wrist→fingertip and thumb→fingertip
#   directions, finger base→tip directions, and the pinch (thumb–index distance), all in the wrist frame.
# - Read the hand terms of the objective (`tip`, `thumb`, `pinch`, `tip_dir`, `finger_dir`, `thumb_gap`) as equations and see them act.
# - See, letter by letter, which fingerspelling handshapes YuMi's Inspire hand can make and which it
#   cannot, and say why from its joints: 6 actuated joints drive 12 finger joints.
# - Move the hand weights on sliders and watch one hand up close.

# %%
from nlo_lab.lab import TEST_MODE, budget, setup

setup()

# %% [markdown]
# ## A human hand from joint angles
#
# The synthetic corpus has a human hand model (`nlo_lab.corpus.arm_kinematics`): per finger an MCP
# flexion, a spread, a PIP and a DIP angle; the thumb a CMC flexion, a CMC abduction, an MCP and an IP
# angle: 20 joints. `nlo_lab.corpus.fingerspelling` holds letters of the one-handed manual alphabet as
# such angles (our own estimates) and spells them with the right hand held up, palm forward, one frame
# per letter.

# %%
from nlo_lab.corpus.fingerspelling import LETTERS, fingerspelling_demonstration, hand_landmarks

letters = "".join(LETTERS) if not TEST_MODE else "ALOVX"
demo = fingerspelling_demonstration(letters)
print(len(demo), "frames:", " ".join(demo.meta["letters"]))
print("L, wrist frame [m]: wrist, thumb tip, index tip\n", hand_landmarks("L")[[0, 4, 8]].round(3))

# %% [markdown]
# ## The robot's hand: 6 motors, 12 finger joints
#
# Each Inspire hand has six actuated joints: thumb yaw and pitch, and one proximal (MCP) joint per
# finger. Six more joints follow them through fixed couplings (URDF `<mimic>`): each finger's middle
# joint turns `1.06·q − 0.045` with its proximal joint, the thumb's two outer joints `1.33·q` and
# `0.67·q` with its pitch. No joint spreads the fingers sideways. The cell counts them from the robot's
# description.

# %%
from nlo_lab.evaluation.hands import finger_chains, hand_joint_indices
from nlo_lab.robot import load_robot

robot = load_robot("yumi")
moving = [robot.model.parent_joint(link) for chain in finger_chains(robot, "right").values() for link in chain[1:]]
moving = {j.name: j for j in moving if j.moving}
coupled = {n: j.mimic for n, j in moving.items() if j.mimic}
print(f"right hand: {len(moving)} finger joints, {len(hand_joint_indices(robot, 'right'))} actuated, {len(coupled)} coupled")
for name, (source, mult, off) in coupled.items():
    print(f"  {name.removeprefix('yumi_hand_r_'):28s} = {mult:.3f} · {source.removeprefix('yumi_hand_r_')} {off:+.3f}")

# %% [markdown]
# ## The hand terms
#
# In the wrist frame (`R_w`: the robot's wrist link turned to the human convention; `R̂_w` the human's),
# with `l_h`, `l̂_h` the hand lengths (mean wrist→knuckle distance of the four fingers), the objective
# adds (`nlo_lab.objective.terms`):
#
# - `L_tip = Σ_side Σ_finger ‖R_wᵀ(p_tip − p_w)/l_h − R̂_wᵀ(p̂_tip − p̂_w)/l̂_h‖²`: wrist→fingertip
#   vectors, the human's scaled to the robot's hand (the "vector" retargeting of DexPilot and
#   dex-retargeting);
# - `L_thumb = Σ_side Σ_(f≠thumb) ‖u(R_wᵀ(p_f − p_th)) − u(R̂_wᵀ(p̂_f − p̂_th))‖²`, `u(v) = v/‖v‖`: the
#   direction from the thumb tip to each other fingertip, where the thumb sits against each finger
#   (directions: the two hands' proportions differ; how close the thumb comes is the pinch's job);
# - `L_pinch = Σ_side Σ_(f≠thumb) a(d̂)·((d − max(d̂, d_min))₊)²`: when the human's thumb and a fingertip
#   touch (`a(d̂)` = 1 below 0.3 hand lengths, fading out at 0.6), the robot's are drawn together, but
#   never below `d_min`, the closest this hand's thumb and that finger can come at all;
# - `L_tip_dir = Σ_side Σ_finger chord(u(R_wᵀ(p_tip − p_w)), u(R̂_wᵀ(p̂_tip − p̂_w)))`, `chord(u, û) = √(‖u − û‖² + ε²) − ε`,
#   and `L_finger_dir = Σ_side Σ_finger ‖u(R_wᵀ(p_tip − p_base)) − u(R̂_wᵀ(p̂_tip − p̂_base))‖²`: where each
#   fingertip points from the wrist and how each finger is bent, as directions in the wrist frame
#   (`2 sin(θ/2)` ≈ `θ` and `2 − 2 cos θ` of exactly the angles `θ` measured above: the fingertip term
#   costs each finger about its angle, as the measure averages angles, so a fingertip this hand cannot
#   point right does not take the effort the others need);
# - `L_gap = Σ_side Σ_(f≠thumb) e²`, `e = d − d̂` (or `(d − d_min)₊` where `d̂ < d_min`): the thumb–fingertip
#   distances follow the human's both ways in every frame, not only while the human pinches.
#
# `tip_dir`, `finger_dir` and `thumb_gap` weigh the **hand stage**: after the latent optimisation, the
# pipeline moves the hand joints alone (60 Adam steps) on the whole objective, the arms kept
# (`nlo_lab.inference.hand_stage`).
#
# The paper's finger term (`finger`, base→tip directions) stays. `d_min` per finger, in hand lengths:

# %%
import torch

from nlo_lab.objective import LossWeights, point_plan

plan = point_plan(robot, torch.float32)
floor = plan.pinch_floor()
for (_, kf), d in zip(plan.thumb_pairs.tolist(), floor.tolist(), strict=True):
    if plan.finger_side[kf] == 1:
        print(f"thumb → {['thumb', 'index', 'middle', 'ring', 'pinky'][plan.finger_index[kf]]:6s} d_min = {d:.2f}")
print(LossWeights())

# %% [markdown]
# ## The gallery: each letter, the human hand beside the robot's
#
# nlo_lab retargets the letters (encoder and latent optimisation, the smoothness term off: the letters
# are separate shapes), and, for comparison, the best the hand can do: its 12 hand joints alone
# optimised on the hand terms (`best_hand_angles`), the arms left where nlo_lab put them.

# %%
import numpy as np

from nlo_lab.evaluation.hands import best_hand_angles, hand_scores, robot_hand_points
from nlo_lab.inference import OptimizeSettings
from nlo_lab.pipeline import RetargetConfig

weights = LossWeights(smooth=0.0)
result = RetargetConfig(robot, settings=OptimizeSettings(iterations=budget(100, 20)), weights=weights, retime=False).build()(demo)
q = np.asarray(result.trajectory.angles, dtype=np.float64)
best = best_hand_angles(robot, q, demo, weights, steps=budget(200, 30))
scores, best_scores = hand_scores(robot, q, demo), hand_scores(robot, best, demo)
right = scores.side == 1
print(f"right hand, mean over {right.sum()} letters: wrist→tip {scores.tip[right].mean():.1f}°, "
      f"thumb→tips {scores.thumb[right].mean():.1f}°, base→tip {scores.finger[right].mean():.1f}°")

# %%
from nlo_lab.viz import handshape_gallery

robot_hands = robot_hand_points(robot, q, "right")
humans = [hand_landmarks(c) * float(plan.hand_length[1]) / float(np.linalg.norm(hand_landmarks(c)[[5, 9, 13, 17]], axis=1).mean())
          for c in letters]
frames = scores.frame[right]
captions = [f"tip {scores.tip[right][i]:.0f}°, thumb {scores.thumb[right][i]:.0f}°" for i in range(len(frames))]
fig = handshape_gallery(list(letters), humans, [{f: p[t] for f, p in robot_hands.items()} for t in frames], captions)

# %% [markdown]
# ## Which finger carries the error
#
# The wrist→fingertip measure is a mean over five fingers; `scores.tip_fingers` keeps each finger's
# error. Per finger, over the letters of the right hand: nlo_lab's, and the hand's with its 12 joints
# free on the hand terms (`best_hand_angles`). That optimum weighs all the hand terms together, not this
# measure alone, so a finger can score better in nlo_lab's pose: the terms trade one fingertip's direction
# against the thumb's place and the other fingers'. A finger whose error stays high in both is one this
# hand cannot point right.

# %%
import matplotlib.pyplot as plt

finger_names = ["thumb", "index", "middle", "ring", "little"]
ours_f, best_f = scores.tip_fingers[right].mean(0), best_scores.tip_fingers[right].mean(0)
fig_f, ax = plt.subplots(figsize=(6, 2.6))
x = np.arange(5)
ax.bar(x - 0.2, ours_f, 0.4, label="nlo_lab")
ax.bar(x + 0.2, best_f, 0.4, label="12 joints free, hand terms")
ax.set_xticks(x, finger_names)
ax.set_ylabel("wrist→tip error [°]")
ax.legend(frameon=False)
plt.show()
worst = int(np.argmax(ours_f))
print(f"largest error: the {finger_names[worst]}, {ours_f[worst]:.1f}° (12 joints free: {best_f[worst]:.1f}°)")

# %% [markdown]
# ## Which letters this hand can make, and why not
#
# A letter counts as **made** when even the best hand pose is within 20° on both direction measures
# (our threshold, a choice: change it and rerun). What the hand lacks for a letter comes from the
# human's joint angles: fingers **spread** apart (no joint for it), a finger bent at its middle joint
# but not at its knuckle, or the other way round (the middle joint follows the knuckle: a **hook**
# cannot be made), the thumb **pinching** a finger it cannot reach (`d_min`).

# %%
from nlo_lab.corpus.fingerspelling import letter_angles
from nlo_lab.objective import PINCH_ON

DEG = 180 / np.pi


def reasons(letter: str) -> list[str]:
    a = letter_angles(letter) * DEG  # (5, 4): thumb..pinky
    out = []
    if np.abs(a[1:, 1]).max() > 6:
        out.append("spread")
    if (np.abs(a[1:, 2] - 1.06 * a[1:, 0]) > 35).any():
        out.append("hook")
    tips = hand_landmarks(letter)[[4, 8, 12, 16, 20]]
    d = np.linalg.norm(tips[1:] - tips[0], axis=1) / np.linalg.norm(hand_landmarks(letter)[[5, 9, 13, 17]], axis=1).mean()
    far = [f for f in range(4) if d[f] < PINCH_ON and floor[4 + f] > d[f] + 0.1]
    if far:
        out.append("pinch beyond reach (" + ", ".join(["index", "middle", "ring", "pinky"][f] for f in far) + ")")
    return out


print(f"{'letter':6s} {'nlo_lab tip/thumb':>18s} {'best tip/thumb':>15s}  made?  what the hand lacks")
made = []
for i, letter in enumerate(letters):
    k = np.flatnonzero((scores.frame == i) & right)[0]
    ok = best_scores.tip[k] <= 20 and best_scores.thumb[k] <= 20
    made.append(ok)
    why = ", ".join(reasons(letter)) or "-"
    print(f"{letter:6s} {scores.tip[k]:8.1f}° {scores.thumb[k]:6.1f}°  {best_scores.tip[k]:7.1f}° {best_scores.thumb[k]:5.1f}°  "
          f"{'yes' if ok else 'no':5s}  {why}")
print(f"\nmade: {''.join(c for c, m in zip(letters, made, strict=True) if m) or '-'}; "
      f"not made: {''.join(c for c, m in zip(letters, made, strict=True) if not m) or '-'}")

# %% [markdown]
# ## The hand weights, live
#
# `HandPanel` re-optimises one letter with the weights on its sliders (`finger`, `tip`, `thumb`,
# `pinch`, `tip_dir`, `finger_dir`, `thumb_gap`; the latent optimisation, then the hand stage) and shows the robot
# framed on its right hand; the red spheres above it are the human's wrist and fingertips at the robot
# hand's size, in the robot's wrist frame: where the fingertips should be. Its `search` list names the fingers
# whose motor the hand stage searches before its descent (the next section; at first the pipeline's: middle, ring,
# little), and its *handshape preset* button sets
# the preset's weights and search at once.
# Try the letter V with `tip` and `tip_dir` at 0.1, then `tip` at 1000: the robot cannot spread, so only
# the curl follows.

# %%
from nlo_lab.lab import HandPanel

panel = HandPanel(demo, robot, weights=weights, frame=min(3, len(demo) - 1), iterations=budget(60, 10))
panel.widget

# %%
panel.controls["tip"].value = 1000.0
print(panel.measures)

# %% [markdown]
# ## Two basins per finger: the search and the handshape preset
#
# Each Inspire finger is one motor, and along it the objective can have two valleys: the finger curled, and
# the finger open. The hand stage's Adam steps stay in the valley the decoder's hands start in. So the stage
# first tries `hand_grid` (16) values of some fingers' motors in every frame and picks the cheapest path through
# them over the whole clip whose steps the robot can play at the clip's pace (dynamic programming,
# `path_within_caps`); then Adam polishes. By default it searches the middle, ring and little fingers
# (`OptimizeSettings().hand_search` is None: the fingers of `HAND_SEARCH` the robot's hands move alone; the index
# is left out: searched, it opens and the thumb–index distance loses the human's course); `hand_search=()` turns
# the search off. The handshape preset (`nlo-lab retarget --handshape`) searches the same fingers, weighs the
# thumb and the base→tip directions more (`LossWeights.handshape()`) and lets the hands slow the robot down: each
# segment of the retimed motion may take up to `hand_slowdown` (1.7) times the latent optimisation's
# (`OptimizeSettings.handshape()`; the defaults' hands never slow it down). Here the three run on the real
# recording of notebook 02; the plot shows the objective (the default weights) along the right ring finger's
# motor in the first frame where it has two valleys (else where the search moved it most), and where each run put
# it; the table the four measures and the retimed duration.

# %%
from nlo_lab.human import load_demonstration
from nlo_lab.inference import HANDSHAPE_SEARCH
from nlo_lab.lab import recording_path

real = load_demonstration(recording_path())
budgets = {"iterations": budget(40, 10), "hand_iterations": budget(60, 10)}
runs = {"no search": RetargetConfig(robot, settings=OptimizeSettings(hand_search=(), **budgets)).build()(real),
        "defaults": RetargetConfig(robot, settings=OptimizeSettings(**budgets)).build()(real),
        "handshape preset": RetargetConfig(robot, settings=OptimizeSettings.handshape(**budgets),
                                           weights=LossWeights.handshape()).build()(real)}
import torch

from nlo_lab.objective import Objective, targets_from_demonstration

# the objective along the right ring motor, frame by frame, the rest of the robot as the run without the search
# left it: the table the search builds (48 values here, 16 in the search)
ring = robot.joint_names.index("yumi_hand_r_ring_proximal_joint")
q_run = {name: torch.as_tensor(np.array(r.trajectory.angles), dtype=robot.lower_limits.dtype) for name, r in runs.items()}
T, values = len(real), torch.linspace(float(robot.lower_limits[ring]), float(robot.upper_limits[ring]), 48)
trial = q_run["no search"].repeat_interleave(len(values), 0)
trial[:, ring] = values.repeat(T)
targets = targets_from_demonstration(real).index(torch.arange(T).repeat_interleave(len(values)))
with torch.no_grad():
    table = Objective(robot, targets, LossWeights())(trial)[0].reshape(T, len(values)).numpy()
inner = (table[:, 1:-1] < table[:, :-2]) & (table[:, 1:-1] < table[:, 2:])
valleys = inner.sum(1) + (table[:, 0] < table[:, 1]) + (table[:, -1] < table[:, -2])  # local minima, the ends too
two = np.flatnonzero(valleys >= 2)
print(f"frames where the right ring's objective has two valleys or more: {len(two)} of {T}")
t = int(two[0]) if len(two) else int((q_run["defaults"][:, ring] - q_run["no search"][:, ring]).abs().argmax())
cost = table[t]
fig_r, ax = plt.subplots(figsize=(6, 2.4))
ax.plot(values, cost, color="0.3")
for (name, qq), c in zip(q_run.items(), ("C7", "C0", "C1"), strict=True):
    ax.axvline(float(qq[t, ring]), color=c, label=f"{name}: {float(qq[t, ring]):.2f} rad")
ax.set(xlabel="right ring motor [rad] (0: open)", ylabel=f"objective, frame {t}")
ax.legend(frameon=False, fontsize=8)
plt.show()
print(f"{'':18s} {'wrist→tip':>9s} {'thumb→tips':>10s} {'base→tip':>9s} {'pinch r':>8s} {'retimed':>8s}")
measures = {name: hand_scores(robot, np.asarray(run.trajectory.angles, dtype=np.float64), real).summary()
            for name, run in runs.items()}
for name, m in measures.items():
    print(f"{name:18s} {m['tip_deg']:8.1f}° {m['thumb_deg']:9.1f}° {m['finger_deg']:8.1f}° {m['pinch_r']:8.2f} "
          f"{runs[name].trajectory.duration:7.2f} s")


def better(a: dict, b: dict) -> str:
    """The measures on which ``a`` is better than ``b``."""
    wins = [k for k in ("tip_deg", "thumb_deg", "finger_deg") if a[k] < b[k]] + (["pinch_r"] if a["pinch_r"] > b["pinch_r"] else [])
    return ", ".join(wins) or "none"


print(f"on this clip the defaults are better than no search on: {better(measures['defaults'], measures['no search'])}")
print(f"on this clip the preset is better than the defaults on: {better(measures['handshape preset'], measures['defaults'])}")

# %% [markdown]
# On the panel, the preset's button (`panel.use_weights` with the preset's weights and fingers, one update) on the
# letter the panel shows:

# %%
before = dict(panel.measures)
panel.use_weights(LossWeights.handshape(), HANDSHAPE_SEARCH)
print(f"searched: {', '.join(panel.settings.hand_search)}; tip_dir {panel.weights.tip_dir:.0f}, thumb {panel.weights.thumb:.0f}")
for key, label in (("tip_deg", "wrist→tip"), ("thumb_deg", "thumb→tips"), ("finger_deg", "base→tip")):
    print(f"{label:10s} {before[key]:6.1f}° -> {panel.measures[key]:6.1f}°")

# %% [markdown]
# One short clip decides little, and the search and the weights were chosen on real recordings (the preset's search
# and first weights on four, its `finger_dir` weight and slowdown on eight; the defaults' `tip_dir` weight and search
# on the eight).
# The numbers of `benchmarks/hands.py` (nlo_lab and the preset against dex-retargeting on every
# real recording we have, on four recordings added after the preset's choice apart, how sure each margin is,
# and on held-out synthetic clips) are in `docs/RESULTS.md`, section "Handshapes".
#
# ## Exercises
#
# 1. Set `thumb=0` and `pinch=0` in `weights` and rerun the gallery. Which letters lose their thumb, and
#    does the wrist→tip error get better or worse? Explain with the two terms' equations.
# 2. Add a letter of your own to `LETTERS` (e.g. K or R) from joint angles. Predict from the robot's
#    joints whether the hand can make it before you look at the table.
# 3. For O, compare the human's thumb–index distance with `d_min`. Why does the pinch term not pull the
#    robot's tips closer than the human's?
# 4. The Inspire thumb has two motors. Which of the human thumb's four angles can it follow, and which
#    letters would a third thumb motor fix?
# 5. In the frame the basins plot shows, where did each run put the ring, and is that the lower valley? Plot the
#    runs' ring motor over the clip beside `two` and the speed caps (`nlo_lab.inference.hand_stage.step_caps`):
#    why can the search not always take the lower valley?
