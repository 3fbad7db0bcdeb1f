# %% [markdown]
# # 08. Retarget your own recording
#
# ## Learning goals
#
# - Retarget a real MediaPipe Holistic recording (`.pose`) to any of the three robots with one call.
# - Check the result: tracking error, joint limits, self-collision, and the trajectories against the limits.
# - Export the trajectory (`.npz`, `.csv` for a real robot) and a self-contained 3-D viewer page.
# - See why raw per-frame retargeting jerks, and how the smoothness weight, the warm start and retiming make
#   a motion the robot can play within its joint velocity limits.
# - Do the same on your own file from the command line: `nlo-lab retarget`.

# %%
from nlo_lab.lab import TEST_MODE, budget, setup

setup()

# %% [markdown]
# ## Your recording
#
# Record signing with MediaPipe Holistic and save it in the `.pose` format (the `pose-format` package,
# e.g. its `video_to_pose` command). Here we use the short recording shipped with the lab; replace `path`
# with your own file (`.pose`, the authors' `.h5`, or our `.npz`).

# %%
from nlo_lab.human import load_demonstration
from nlo_lab.lab import recording_path

path = recording_path()                    # or: path = "my_signing.pose"
demo = load_demonstration(path)
print(f"{path.name}: {len(demo)} frames at {demo.fps} fps")

# %% [markdown]
# ## Retarget
#
# `retarget` builds the targets, starts every frame from the encoder and optimises the latents with the
# shipped model of the robot; it returns the trajectory and the quality figures.

# %%
from nlo_lab.inference import OptimizeSettings
from nlo_lab.pipeline import retarget
from nlo_lab.robot import load_robot

robot = load_robot("yumi")                 # or "nao", "pepper"
result = retarget(demo, robot, settings=OptimizeSettings(init="encoder", iterations=budget(100, 10)))
for key, value in result.summary.items():
    print(f"{key:22s} {value}")

# %%
from nlo_lab.lab import show_view

show_view(robot, result.trajectory.angles, demo=demo)

# %%
from nlo_lab.viz import plot_joint_trajectories

plot_joint_trajectories(result.trajectory.angles, robot.joint_names, robot.lower_limits, robot.upper_limits,
                        fps=demo.fps, joints=range(min(8, robot.n_joints)));

# %% [markdown]
# ## Export
#
# `trajectory.npz` (angles, joint names, fps, robot, and `time`: when each frame plays), `trajectory.csv`
# (one row per frame: `time_s`, then one column per joint, for a real robot's controller) and `viewer.html` (opens offline in any browser: robot beside the
# human, with play and scrub). They go into `nlo_lab_work/retargeted/` beside this notebook (`work_folder`; the
# variable `NLO_LAB_WORK` chooses another place), never into the package.

# %%
from nlo_lab.lab import work_folder
from nlo_lab.viz import export_html

out = work_folder("retargeted")
result.trajectory.save_npz(out / "trajectory.npz")
result.trajectory.save_csv(out / "trajectory.csv")
export_html(out / "viewer.html", robot, result.trajectory.angles, demo=demo)
print(out.resolve(), sorted(p.name for p in out.iterdir()))
print((out / "trajectory.csv").read_text().splitlines()[0][:120], "...")

# %% [markdown]
# ## Every robot
#
# The same recording on the three robots. The tracking error is in metres after the human arm has been
# scaled to each robot's arm length.

# %%
for name in budget(("yumi", "nao", "pepper"), ("nao",)):
    s = retarget(demo, load_robot(name), settings=OptimizeSettings(iterations=budget(100, 10))).summary
    print(f"{name:7s} Fréchet {s['frechet_m'] * 100:5.1f} cm, collision frames {s['self_collision_frames']}, "
          f"limit violations {s['limit_violations']}, {s['seconds']:.2f} s")

# %% [markdown]
# ## Smooth, and within the robot's speed limits
#
# The paper optimises every frame on its own: it has "no mechanism to ensure smoothness". On a real
# recording that can show: the encoder can pick another arm configuration from one frame to the next, and
# noise in the landmarks becomes joint jitter, faster than the robot's motors can turn (each joint's limit is
# in `robot.velocity_limits`). Three things fix it, in this order:
#
# 1. **the smoothness term** `smooth` (`LossWeights`): each joint's speed between consecutive frames, in
#    units of its velocity limit, squared, added to `L(D, K(q))` over the whole sequence;
# 2. **the warm start** along the sequence: a frame may start from a neighbour's latent, so neighbouring
#    frames start in the same arm configuration;
# 3. **retiming**: what is still faster than a joint's limit is slowed down (the trajectory's `time`), never
#    the other way round. The summary's `slowdown` says by how much, `velocity_violations` counts frame
#    pairs over a limit on the file's own time base (0 after retiming).
#
# The reader also cleans the landmarks first (outlier frames repaired, Savitzky-Golay smoothing, hands scaled
# to the forearm): `demo.meta["conditioning"]`. Compare `smooth=0` (the paper) with the default:

# %%
from nlo_lab.objective import LossWeights
from nlo_lab.viz import plot_joint_speeds

ITERS = budget(100, 10)
rough = retarget(demo, robot, weights=LossWeights(smooth=0), settings=OptimizeSettings(iterations=ITERS))
smooth = retarget(demo, robot, settings=OptimizeSettings(iterations=ITERS))
for label, r in (("smooth=0", rough), (f"smooth={LossWeights().smooth:g}", smooth)):
    s = r.summary
    print(f"{label:10s} Fréchet {s['frechet_m']:.3f} m, speed/limit at the recorded rate {s['recording_speed_ratio']:5.2f}, "
          f"largest step {s['max_joint_step_rad']:.2f} rad, slowdown {s['slowdown']:.2f}, velocity violations {s['velocity_violations']}")
plot_joint_speeds(robot, {"smooth=0, not retimed": rough.trajectory.at_frame_rate(), "smooth, retimed": smooth.trajectory})
import matplotlib.pyplot as plt
from IPython.display import Markdown

plt.show()
a, b = rough.summary, smooth.summary
Markdown(f"At the recorded rate, the fastest joint turns at **{a['recording_speed_ratio']:.2f}×** its limit without the "
         f"smoothness term and **{b['recording_speed_ratio']:.2f}×** with it (largest step {a['max_joint_step_rad']:.2f} against "
         f"{b['max_joint_step_rad']:.2f} rad). Retiming then plays the smooth result {b['slowdown']:.2f}× as long as the "
         f"recording, with {b['velocity_violations']} velocity violations; the Fréchet distance goes from "
         f"{a['frechet_m']:.3f} to {b['frechet_m']:.3f} m.")

# %% [markdown]
# Move the slider: the smoothness weight trades tracking (Fréchet) against speed. The dashed lines are the
# joints' published velocity limits; the curves are on each trajectory's own time base, so the retimed one
# is longer where the robot had to slow down.

# %%
import ipywidgets as widgets
import matplotlib.pyplot as plt


def show_smoothness(smooth_weight=LossWeights().smooth):
    r = retarget(demo, robot, weights=LossWeights(smooth=smooth_weight), settings=OptimizeSettings(iterations=ITERS))
    s = r.summary
    print(f"smooth={smooth_weight:g}: Fréchet {s['frechet_m']:.3f} m, largest step {s['max_joint_step_rad']:.2f} rad, "
          f"slowdown {s['slowdown']:.2f}")
    plot_joint_speeds(robot, {"at the recorded rate": r.trajectory.at_frame_rate(), "retimed": r.trajectory})
    plt.show()
widgets.interact(show_smoothness, smooth_weight=widgets.FloatSlider(value=LossWeights().smooth, min=0, max=50, step=1,
                                                                   continuous_update=False));

# %% [markdown]
# The 3-D motion without the smoothness term (first) and with it (second): watch the wrists.

# %%
show_view(robot, rough.trajectory.angles, demo=demo)

# %%
show_view(robot, smooth.trajectory.angles, demo=demo)

# %% [markdown]
# ## From the command line
#
# The same in a terminal (`--json` prints the summary as one line of JSON; a bad file ends with exit
# status 2 and one line saying what is wrong):
#
# ```
# nlo-lab retarget my_signing.pose --robot nao --iters 100 --out retargeted_nao
# ```

# %%
import subprocess
import sys

cmd = [sys.executable, "-m", "nlo_lab.cli", "retarget", str(path), "--robot", "nao", "--iters", str(budget(100, 5)), "--json"]
print(subprocess.run(cmd, capture_output=True, text=True, check=True).stdout)

# %% [markdown]
# ## A whole corpus: `nlo_lab.batch`
#
# A corpus is hundreds of recordings. `retarget_many` retargets every file of a folder (searched recursively
# for `.pose .h5 .npz .mp4 .mov .webm .avi`), of a list or of a manifest, on a
# [dask.distributed](https://distributed.dask.org) cluster: by default a `LocalCluster` of worker processes
# on this machine, one per core (at most one per input), each loading the model once. On a lab's cluster pass its `client=` (or
# `scheduler="tcp://HOST:PORT"`). Each input gets its own folder (what `nlo-lab retarget --out` writes, plus
# `summary.json`) and `results.csv` one row per input: its status, its error if it failed, the quality
# figures. From a terminal: `nlo-lab batch my_corpus/ --robot nao --out retargeted/`.
#
# A small corpus: the recording above, a few clips of the synthetic corpus saved as `.npz`, and a damaged file.

# %%
import shutil

from nlo_lab.corpus import corpus_clip, corpus_names
from nlo_lab.human import save_npz

shutil.rmtree(work_folder("batch"))          # afresh at every run: the first run below works, the second skips
corpus = work_folder("batch") / "corpus"
(corpus / "synthetic").mkdir(parents=True)
shutil.copy(path, corpus / path.name)
for name in corpus_names("test")[:budget(6, 2)]:
    save_npz(corpus_clip(name), corpus / "synthetic" / f"{name}.npz")
(corpus / "damaged.pose").write_bytes(b"not a recording")
print(sorted(str(p.relative_to(corpus)) for p in corpus.rglob("*.*")))

# %%
from nlo_lab.batch import retarget_many

batch_out = corpus.parent / "retargeted"
rows = retarget_many([corpus], "nao", batch_out, iterations=budget(100, 10), progress=True)
rows = rows.to_dict("records") if hasattr(rows, "to_dict") else rows  # a pandas DataFrame when pandas is installed
for row in rows:
    print(f"{row['output']:28s} {row['status']:7s} {row['frames'] or '':>4} frames {row['error'] or ''}")
first = next(r for r in rows if r["status"] == "ok")
print(first["output"], "->", sorted(p.name for p in (batch_out / first["output"]).iterdir()))

# %% [markdown]
# The results table as pictures: how closely each input is tracked, and where the time goes (the workers'
# seconds for each input against its frames).

# %%
done = [r for r in rows if r["status"] != "failed"]
fig, (left, right) = plt.subplots(1, 2, figsize=(11, 3.2))
left.barh([r["output"] for r in done], [r["frechet_m"] * 100 for r in done])
left.set_xlabel("Fréchet distance [cm]")
left.set_title(f"{len(done)} retargeted, {len(rows) - len(done)} failed")
right.scatter([r["frames"] for r in done], [r["seconds"] for r in done])
right.set_xlabel("frames"); right.set_ylabel("worker seconds"); right.set_title("time per input")
fig.tight_layout()

# %% [markdown]
# Run it again: what was done with the same content and settings is skipped, and the damaged file keeps its
# `failed` row without running again (`retry_failed=True` tries it anyway). Nothing is left to run, so no
# cluster starts.

# %%
again = retarget_many([corpus], "nao", batch_out, iterations=budget(100, 10))
again = again.to_dict("records") if hasattr(again, "to_dict") else again
print({status: sum(r["status"] == status for r in again) for status in ("ok", "skipped", "failed")})

# %% [markdown]
# ## Exercises
#
# 1. Retarget with `init="random"` and the same budget. How much larger is the Fréchet distance?
# 2. Retarget with only 10 iterations and with 300. Where does the improvement stop paying?
# 3. Open `viewer.html` in your browser, scrub to a frame where a hand is missing in the recording: what does the robot's hand do?
# 4. Record yourself signing a short phrase, convert it to `.pose`, and retarget it to Pepper.
# 5. Load `trajectory.csv` with numpy and check the joint limits yourself.
# 6. Set the smoothness weight to 0 and retarget to NAO: predict `slowdown` and `max_joint_step_rad` before
#    running. Then check the joint speeds in `trajectory.csv` against `robot.velocity_limits` with its `time_s` column.
# 7. Run `retarget_many` on a folder of your own recordings with `viewer=True`, then again with more
#    iterations: which rows say `skipped` the second time, and why not?
