# %% [markdown]
# # 10. Your own robot
#
# ## Learning goals
#
# - Turn a robot's URDF into a complete nlo_lab spec with one call (`nlo-lab robot init` on the command
#   line): arms, fingers, actuated and fixed joints, velocity limits, the robot frame, the wrist
#   alignment and the collision capsules, all derived from the URDF.
# - See the robot as it looks (its meshes) and what the self-collision term sees (capsules fitted to its
#   collision geometry), and check the spec (`nlo-lab robot check`).
# - Train its encoder and decoder briefly, retarget a real recording, and compare with YuMi side by side.
# - Learn what each field of the spec changes, by changing one at a time.

# %%
from nlo_lab.lab import TEST_MODE, budget, setup

setup()

# %% [markdown]
# ## A URDF of your own
#
# The lesson ships a robot written for it: a pedestal, a torso, a head on a neck joint, two 6-joint arms
# and 3-finger hands whose distal finger joints follow the proximal ones (`<mimic>`). Every link is a mesh
# file (made with trimesh), referred to by a path relative to the URDF, as real robots' descriptions do.
# Use your own robot's `.urdf` instead (a `.xacro` must be expanded first: `xacro robot.urdf.xacro > robot.urdf`).

# %%
from nlo_lab.lab import lesson_urdf
from nlo_lab.robot import parse_urdf

urdf = lesson_urdf()                            # or: urdf = "my_robot.urdf"
model = parse_urdf(urdf)
moving = [j for j in model.joints if j.type != "fixed"]
print(f"{urdf.name}: {len(model.links)} links, {len(moving)} moving joints, root {model.root!r}")
print("mesh files:", sorted({p.name for p in (urdf.parent / "meshes").glob("*.stl")}))

# %% [markdown]
# ## Draft the spec
#
# `draft_spec` is what `nlo-lab robot init URDF --out SPEC.json` runs. It finds the two arms from the tree and
# the names (and prints the six links it chose: give `left_arm=(shoulder, elbow, wrist)` to correct them),
# finds the fingers below each wrist by name, actuates the joints on the chains from the base to the wrists
# and fingertips (the neck is fixed), takes the velocity limits from the URDF, places the robot frame between
# the shoulders, derives the wrist alignment from the finger bases and fits capsules to the collision meshes.
# Where two links' capsules touch at the rest pose though their meshes do not (a capsule is rounder than the
# mesh inside it), the pair cannot be kept apart without leaving the rest pose, so the draft leaves it unchecked
# and says so: a warning below the cell names the pairs, a `note:` line in the summary counts them. Read them for
# your own robot: the optimiser does not keep an unchecked pair apart.

# %%
from nlo_lab.lab import work_folder
from nlo_lab.robot import draft_spec
from nlo_lab.robot.spec import spec_text

spec_path = work_folder("own_robot") / "lesson_robot.json"
draft = draft_spec(urdf, spec_path, samples=budget(4000, 300))
spec_path.write_text(spec_text(draft.spec))
print("\n".join(draft.summary()))
robot = draft.robot

# %% [markdown]
# The robot as it looks (its visual meshes, decimated to a face budget so that the scene stays light), with
# the capsules of its spec over it in red: each collision mesh lies inside a capsule, so capsules apart means
# the meshes apart. The optimiser keeps the capsules of every checked pair apart.

# %%
from nlo_lab.lab import show_robot

show_robot(robot, capsules=True)

# %% [markdown]
# `check_spec` is `nlo-lab robot check SPEC.json`: it loads the spec against its URDF (an unknown link gets the
# closest names in the URDF) and summarises it.

# %%
from nlo_lab.robot import check_spec, spec_summary

print("\n".join(spec_summary(check_spec(spec_path))))

# %% [markdown]
# ## Train briefly
#
# The encoder and decoder learn this robot's joints on the synthetic sign corpus (paper Eq. 10), as
# `nlo-lab train --robot SPEC.json --out CKPT.pt` does. A few minutes give a usable model; the latent
# optimisation at retargeting does the rest. A robot of your own first tries three starts (`TrainSettings.starts`):
# seeds 0, 1 and 2 train a while each, and the one with the lowest validation objective goes on. One start can
# settle where no later step leads out (a drafted Romeo's elbows swung out in some seeds: README, "Your own robot").

# %%
from nlo_lab.model import save_checkpoint
from nlo_lab.training import TrainSettings, train_model

trained = train_model(robot, TrainSettings(max_seconds=budget(240, 8), progress=True))
checkpoint = save_checkpoint(trained.model, spec_path.with_suffix(".pt"), robot)
chosen = min(trained.starts, key=lambda start: start["val"])
others = ", ".join(f"{start['val']:.1f}" for start in trained.starts if start is not chosen)
print(f"the best of {len(trained.starts)} starts: seed {chosen['seed']}, validation objective {chosen['val']:.1f} after its "
      f"first {chosen['steps']} steps (the others: {others or 'none'})")
print(f"{trained.steps} steps in {trained.seconds:.0f} s, validation loss {trained.val_loss:.3f}; {checkpoint.name}")

# %% [markdown]
# ## Retarget a recording, beside YuMi
#
# The same real recording to the lesson robot (its checkpoint: `checkpoint=` in `retarget`, `--checkpoint` on the
# command line) and to YuMi. Their arms are of other lengths than the signer's: the objective compares the
# wrist relative to the shoulder in units of arm length and the forearm in units of its length, so no
# scaling is needed. The lesson robot has no ring and little fingers: those are not targeted.

# %%
import ipywidgets as widgets
from IPython.display import Markdown

from nlo_lab.evaluation import direction_error
from nlo_lab.human import load_demonstration
from nlo_lab.inference import OptimizeSettings
from nlo_lab.lab import recording_path, show_view
from nlo_lab.pipeline import retarget
from nlo_lab.robot import load_robot

demo = load_demonstration(recording_path())
demo = demo.slice(0, budget(len(demo), 15))
settings = OptimizeSettings(iterations=budget(100, 10))
yumi = load_robot("yumi")
ours = retarget(demo, robot, checkpoint=checkpoint, settings=settings)
theirs = retarget(demo, yumi, settings=settings)
errors = {name: direction_error(r, demo, res.trajectory.angles) for name, r, res in (("lesson robot", robot, ours), ("YuMi", yumi, theirs))}
widgets.HBox([show_view(robot, ours.trajectory.angles, demo=demo, height=320), show_view(yumi, theirs.trajectory.angles, height=320)])

# %%
rows = [f"| {name} | {e['mean_deg']:.1f}° | {e['rest_deg']:.1f}° | {e['ratio']:.2f} |" for name, e in errors.items()]
better = min(errors, key=lambda n: errors[n]["ratio"])
better = "the lesson robot" if better == "lesson robot" else better
Markdown("The angle between the human's and the robot's shoulder→elbow and shoulder→wrist directions, against the "
         "robot standing still at rest:\n\n| robot | retargeted | at rest | ratio |\n|---|---|---|---|\n" + "\n".join(rows)
         + f"\n\nIn this run {better} follows the signer's arm directions more closely.")

# %% [markdown]
# ## What each field of the spec changes
#
# One field changed at a time in a copy of the spec (`spec_variant`), the same recording and the same
# checkpoint (the joints are the same), and five measures: the arms' direction error, the angle between the
# robot's hand frame and the signer's wrist frame, the Fréchet distance, the slowdown retiming needs, and the
# smallest gap between the two arms' capsules.

# %%
import math

from nlo_lab.lab import retarget_report, spec_variant
from nlo_lab.model import load_checkpoint
from nlo_lab.rotations import matrix_to_rpy, rpy_to_matrix

model = load_checkpoint(checkpoint, robot)


def turn_hands(data):                 # wrist_alignment_rpy: the hand frame turned 90° about the hand's axis
    for arm in data["arms"].values():
        arm["wrist_alignment_rpy"] = list(matrix_to_rpy(rpy_to_matrix(arm["wrist_alignment_rpy"]) @ rpy_to_matrix((math.pi / 2, 0, 0))))


def no_index(data):                   # fingers: a finger the spec does not name is not targeted
    for arm in data["arms"].values():
        arm["fingers"].pop("index")


def slow_joints(data):                # velocity_limits: half as fast
    data["velocity_limits"] = {k: v / 2 for k, v in data["velocity_limits"].items()}


def wide_margin(data):                # collision_margin: keep the capsules 25 cm apart
    data["collision_margin"] = {"default": 0.25}


def turn_frame(data):                 # robot_frame: the robot's "forward" turned 90° to its left
    data["robot_frame"]["rpy"][2] += math.pi / 2


variants = {"as drafted": None, "hands turned 90°": turn_hands, "no index fingers": no_index,
            "joints half as fast": slow_joints, "margin 25 cm": wide_margin, "frame turned 90°": turn_frame}
iterations = budget(60, 8)
table = {label: retarget_report(robot if edit is None else spec_variant(spec_path, label.replace(" ", "_"), edit), demo, model, iterations)
         for label, edit in variants.items()}
Markdown("| spec | direction [°] | hand [°] | Fréchet [m] | slowdown | arms' gap [m] |\n|---|---|---|---|---|---|\n" + "\n".join(
    f"| {label} | {r['direction_deg']:.1f} | {r['hand_deg']:.1f} | {r['frechet_m']:.3f} | {r['slowdown']:.2f} | {r['arms_gap_m']:.3f} |"
    for label, r in table.items()))

# %%
base = table["as drafted"]
Markdown(
    f"Turning the hand frames changes the hand angle from {base['hand_deg']:.0f}° to {table['hands turned 90°']['hand_deg']:.0f}°; "
    f"halving the joint speeds changes the slowdown from {base['slowdown']:.2f} to {table['joints half as fast']['slowdown']:.2f}; "
    f"a 25 cm margin changes the arms' smallest gap from {base['arms_gap_m'] * 100:.1f} to {table['margin 25 cm']['arms_gap_m'] * 100:.1f} cm; "
    f"turning the robot frame changes the arms' direction error from {base['direction_deg']:.0f}° to "
    f"{table['frame turned 90°']['direction_deg']:.0f}°."
)

# %% [markdown]
# The fields a spec has (`docs/ARCHITECTURE.md`, "Spec file"): `actuated_joints` and `fixed_joints` (changing
# them needs a new training: a checkpoint is made for its joints and says so), `arms` (role links, wrist
# alignment, fingers), `capsules`, `collision_pairs` and `collision_margin`, `velocity_limits`, `robot_frame`,
# `neutral_pose` and `srdf`. Edit the JSON, then run `nlo-lab robot check` on it.
#
# ## Exercises
#
# 1. Draft the spec again with `left_hand={}` and `right_hand={}` (no fingers): how many actuated joints are
#    left, and does the robot still retarget the arms? Predict first.
# 2. Give `left_arm=("l_shoulder", "l_upper_arm", "l_hand")` (a wrong elbow): what does `check_spec` print,
#    and how does the direction error change?
# 3. Train for twice as long: how much does the direction error improve, and the validation loss?
# 4. Change `collision_margin` to 0.001 m and to 0.1 m: which measures move, and in which direction?
# 5. Run `nlo-lab robot init` on a robot of `example-robot-data` (`pip install example-robot-data`), e.g.
#    Baxter with its SRDF (`--srdf`): which six links does it choose?
