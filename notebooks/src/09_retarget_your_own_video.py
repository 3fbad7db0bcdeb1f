# %% [markdown]
# # 09. Retarget your own video
#
# ## Learning goals
#
# - Turn a video of signing into a human demonstration: MediaPipe Holistic finds the body and hand
#   landmarks in every frame (through the `pose-format` library), the `.pose` reader of notebook 08 does the rest.
# - See what the pose estimator saw: the video's frames beside the human skeleton and the robot, played in sync.
# - Know the limits of a single camera: hands that leave the picture are masked, depth is a guess.
# - Export the robot trajectory, and do the same from the command line: `nlo-lab retarget VIDEO`.

# %%
from nlo_lab.lab import TEST_MODE, budget, setup

setup()

# %% [markdown]
# ## Your video
#
# Film yourself signing (upper body, both hands in the picture, good light), then choose the file below:
# `.mp4`, `.mov`, `.webm` or `.avi`. Without an upload the notebook uses the short sample shipped with the
# lab (58 frames of a webcam video, MIT licence, see `assets/recordings/README.md`). After choosing a file,
# run the cells below again.

# %%
import ipywidgets as W

upload = W.FileUpload(accept=".mp4,.mov,.webm,.avi", multiple=False, description="your video")
upload

# %%
from nlo_lab.lab import recording_path, save_upload, work_folder

work = work_folder("my_video")             # nlo_lab_work/my_video beside this notebook: uploads and exports
path = save_upload(upload, work) or recording_path("signer_webcam_58f.mp4")
print(path.name)

# %% [markdown]
# ## Pose estimation
#
# `estimate_pose` decodes the video and runs MediaPipe Holistic on every frame (the model ships inside the
# `mediapipe` wheel: nothing is downloaded). It keeps the image landmarks and the *world* landmarks, which
# MediaPipe gives in metres about the hips. The video is cut into segments of 30 frames, each tracked by its
# own Holistic instance; by default one instance runs per core available, `threads=N` (or `NLO_LAB_THREADS`)
# caps that at N. The cut does not depend on N, so neither do the landmarks.
#
# `pose_to_demonstration` then reads the landmarks exactly as the `.pose` reader reads a file: body frame
# from the shoulders, arms from the world landmarks, wrists and fingers from the 21 hand points, short gaps
# filled, long ones masked. A hand that is never seen gives a warning and masked fingers.

# %%
from nlo_lab.human import estimate_pose, pose_to_demonstration, read_video_frames

video = estimate_pose(path, progress=True)
demo = pose_to_demonstration(video)
frames = read_video_frames(path, max_side=360)
print(f"{len(demo)} frames at {demo.fps:.2f} fps; pose estimation {video.seconds:.1f} s "
      f"({len(demo) / video.seconds:.1f} frames/s, {video.workers} worker)")
for side, seen in demo.meta["hands"].items():
    print(f"{side} hand seen in {seen['observed_frames']} of {len(demo)} frames")

# %% [markdown]
# Which frames have each hand? A hand MediaPipe does not find in a frame is masked there (short gaps are
# filled from the neighbouring frames): its fingers and wrist orientation have no target in the objective.

# %%
import matplotlib.pyplot as plt
from IPython.display import Markdown

from nlo_lab.human import load_demonstration

fig, ax = plt.subplots(figsize=(6, 2.2))
for s, side in enumerate(("left", "right")):
    ax.step(range(len(demo)), demo.finger_mask[:, s].all(axis=1), where="mid", label=f"{side} hand")
ax.set(xlabel="frame", ylabel="fingers have a target", yticks=[0, 1], yticklabels=["no", "yes"]); ax.legend(fontsize="small")
plt.show()
seen = {side: demo.meta["hands"][side]["observed_frames"] for side in ("left", "right")}
never = [side for side, n in seen.items() if n == 0]
shipped = load_demonstration(recording_path()).meta["hands"]   # the .pose recording of notebook 08
Markdown(f"MediaPipe found the left hand in **{seen['left']}** and the right hand in **{seen['right']}** of the {len(demo)} frames. "
         + (f"The {' and the '.join(never)} hand{'s are' if len(never) > 1 else ' is'} never seen, so the robot's "
            f"{' and '.join(never)} fingers follow no target in any frame: this video cannot show both hands. "
            if never else "")
         + f"The `.pose` recording of notebook 08 has the left hand in {shipped['left']['observed_frames']} and the right in "
         f"{shipped['right']['observed_frames']} frames; for a video with both hands, film yourself with both in the picture.")

# %% [markdown]
# ## Retarget
#
# The same call as in notebook 08: the encoder's guess, then latent optimisation of the whole clip.

# %%
from nlo_lab.inference import OptimizeSettings
from nlo_lab.pipeline import retarget
from nlo_lab.robot import load_robot

robot = load_robot("yumi")                 # or "nao", "pepper"
result = retarget(demo, robot, settings=OptimizeSettings(iterations=budget(100, 10)))
for key in ("frames", "seconds", "frechet_m", "self_collision_frames", "limit_violations"):
    print(f"{key:22s} {result.summary[key]}")

# %% [markdown]
# ## Video, skeleton and robot in sync
#
# Press play, or drag the slider: the video frame on the left, the human skeleton MediaPipe found (scaled to
# the robot's arms) and the robot on the right, always the same frame. Where a hand is masked (the plot
# above), the robot's fingers on that side have no target: they come from the encoder's guess and the
# smoothness term, not from the video.

# %%
from nlo_lab.lab import VideoView

view = VideoView(frames, robot, result.trajectory.angles, demo)
view.frame = len(demo) // 2
view

# %%
import numpy as np

from nlo_lab.viz import plot_joint_trajectories

plot_joint_trajectories(result.trajectory.angles, robot.joint_names, robot.lower_limits, robot.upper_limits,
                        fps=demo.fps, joints=range(min(8, robot.n_joints)));

# %% [markdown]
# ## Export
#
# The trajectory (`.npz`, and `.csv` for a real robot's controller), the self-contained viewer page, and the
# landmarks as a `.pose` file: reading that file back gives the same demonstration without running the
# pose estimator again.

# %%
from nlo_lab.human import load_demonstration
from nlo_lab.viz import export_html

out = work / "retargeted"
out.mkdir(parents=True, exist_ok=True)
result.trajectory.save_npz(out / "trajectory.npz")
result.trajectory.save_csv(out / "trajectory.csv")
export_html(out / "viewer.html", robot, result.trajectory.angles, demo=demo)
pose_file = out / f"{path.stem}.pose"
pose_file.write_bytes(video.to_bytes())
again = load_demonstration(pose_file)
print(sorted(p.name for p in out.iterdir()))
print("same demonstration from the .pose:", np.array_equal(again.arm_positions, demo.arm_positions, equal_nan=True))

# %% [markdown]
# ## From the command line
#
# ```
# nlo-lab retarget my_signing.mp4 --robot nao --out retargeted_nao --save-pose my_signing.pose --json
# ```
#
# The JSON summary adds `pose_seconds`, the time the pose estimation took; a progress bar shows it running
# when the terminal is interactive. A damaged file, a file that is not a video, or a video without a person
# ends with exit status 2 and one line that says so. (In test mode the cell below runs on the `.pose` saved
# above, which skips the pose estimation.)

# %%
import json
import subprocess
import sys

source = budget(path, pose_file)
cmd = [sys.executable, "-m", "nlo_lab.cli", "retarget", str(source), "--robot", "nao", "--iters", str(budget(100, 5)), "--json"]
run = subprocess.run(cmd, capture_output=True, text=True, check=True)
print(json.dumps(json.loads(run.stdout), indent=1))
print(run.stderr.strip())

# %% [markdown]
# ## Exercises
#
# 1. Film one sign twice, once with your hands always in the picture and once with one hand leaving it.
#    Before running: which fingers will be masked, and what will the robot's hand do in those frames?
# 2. Run the pose estimation with `threads=1`, then `threads=2`. Predict the speed-up on this machine, then
#    measure it (`video.seconds`). Do the landmarks change? (Each segment of 30 frames is tracked on its own.)
# 3. Retarget the same video to NAO and Pepper. Which robot's Fréchet distance is lowest, and why?
# 4. Film yourself from the side instead of the front. Which joint do you expect to be estimated worst?
# 5. Open `viewer.html` from the export folder and compare a fast movement with the video: does the robot keep up?
