# %% [markdown]
# # 11. Live: sign into your camera, watch the robot sign back
#
# ## Learning goals
#
# - Drive a robot with your own arms and hands, live, from the camera of the browser you read this in.
# - Know what runs on every camera frame: MediaPipe Holistic in video mode, a causal landmark filter, the body
#   frame of notebook 08, one-frame latent optimisation warm-started from the last frame, the robot's limits.
# - See what a live retargeter cannot do that the offline one of notebooks 08 and 09 does (look at future frames,
#   slow the motion down) and what it does instead (filter causally, rate limit to the velocity limits).
# - Read the latency and the frame rate, and say what limits them.
# - Keep a session as a `.pose` file and a robot trajectory, and open them like any recording.

# %%
from nlo_lab.lab import TEST_MODE, budget, setup

setup()

# %% [markdown]
# ## The camera view
#
# Press **Start**: the browser asks for your camera. The picture stays in your browser; the page sends the
# kernel one frame at a time over the notebook's own connection (the widget's comm: no server, no port),
# shrunk to 480 pixels on its longer side and compressed as JPEG (20-40 kB). The page sends the next frame
# only when the kernel has answered the last one: when the kernel is slower than the camera, camera frames
# are **dropped, never queued**, so the robot always follows the present. For each frame the kernel runs
# `LiveRetargeter.step(image, t)`: MediaPipe Holistic (video mode: it tracks you from frame to frame), the
# geometry of the `.pose` reader made causal with a One-Euro filter, latent optimisation of that one frame
# starting from the last frame's latent, then the robot's limits. The 3-D view beside the camera follows.
#
# Browsers give the camera to **secure pages** only: `https://...`, or `http://localhost` /
# `http://127.0.0.1` (what `nlo-lab lab` opens). On a JupyterHub or Binder the hub must be served over https;
# for a kernel on another machine, tunnel it (`ssh -L 8888:localhost:8888 host`) and open
# `http://localhost:8888`. The view says so when the page is not secure, when there is no camera, or when the
# camera is refused. Nothing is stored unless you ask (below: `record`).

# %%
from nlo_lab.live import CameraView

view = CameraView(robot="yumi")   # or "nao", "pepper"
view

# %% [markdown]
# No camera (or not yet)? The next cell feeds the sample video's frames through exactly the same path (JPEG,
# decoding, the retargeter, the view) when no camera frame has arrived, so the view, the figures and the plots
# below have something to show. With your camera running it does nothing.

# %%
from IPython.display import HTML

from nlo_lab.lab import recording_path

if view.frames_processed == 0:
    view.play_video(recording_path("signer_webcam_58f.mp4"), frames=budget(58, 20))
HTML(view.summary())

# %% [markdown]
# ## Latency and frame rate
#
# The status line above the camera shows the frames processed, the frame rate (`fps`, processed frames per
# second over the last 3 s) and the latency (`latency_ms`: the median time from a frame's arrival in the kernel
# to the robot's view update). The plot splits each frame's latency into its parts: JPEG decoding, MediaPipe,
# the causal reader with its filter, the optimisation, and the view update (forward kinematics of the drawn
# links and the widget's message). Run the cell again while the camera runs to see the newest frames.

# %%
from nlo_lab.live import plot_latency

plot_latency(view.history);

# %% [markdown]
# ## What limits the frame rate

# %%
from IPython.display import Markdown

split = view.latency_split
total = sum(split.values())
parts = sorted(split.items(), key=lambda kv: -kv[1])
Markdown(
    f"In this run a frame took **{view.latency_ms:.0f} ms** in the kernel (median), so at most "
    f"**{1000 / max(view.latency_ms, 1e-3):.1f} frames per second** can be processed: the page waits for each answer. "
    f"The largest part is **{parts[0][0]}** ({parts[0][1]:.0f} ms, {100 * parts[0][1] / total:.0f} % of the parts), then "
    f"{parts[1][0]} ({parts[1][1]:.0f} ms); {', '.join(f'{k} {v:.0f} ms' for k, v in parts[2:])}. "
    "MediaPipe's models (pose, face mesh and hands; the face mesh runs although nothing here uses it) are fixed in cost; "
    "the optimisation costs about its iterations (slider below) and stops early when the loss stops falling. "
    "Two cores are shared by MediaPipe, the optimiser and, on the same machine, the browser drawing the 3-D view with "
    "WebGL on the CPU: a busy machine is slower. Smaller frames hardly help (MediaPipe crops 256-pixel regions); a "
    "frame rate above the camera's (30 fps) would not help either.")

# %% [markdown]
# ## Steering the running stream
#
# The sliders change the retargeter from its next frame on: the loss weights of notebook 03 (move `ee` to the
# left end to switch the end-effector term off and watch the hands drift), the iterations per frame, and the
# One-Euro filter: `min_cutoff` is how much a landmark at rest is smoothed (lower: steadier, and later), `beta`
# how fast the smoothing lets go when the landmark moves (higher: follows fast signs closely, and lets through
# more jitter while it moves).

# %%
from nlo_lab.live import LiveControls

controls = LiveControls(view.retargeter)
controls

# %% [markdown]
# What the filter does, on the sample video: MediaPipe runs once, then the same landmarks go through the causal
# reader three times: unfiltered, with the default filter, and smoothed hard (`min_cutoff` 0.3 Hz, `beta` 0).
# The right wrist's height in the body frame shows the price of a filter that may not look at the future: the
# steadier the curve, the later it follows.

# %%
import matplotlib.pyplot as plt
import numpy as np

from nlo_lab.human import read_video_frames
from nlo_lab.live import CausalReader, FilterSettings, HolisticTracker

images = read_video_frames(recording_path("signer_webcam_58f.mp4"), max_side=480)[: budget(58, 20)]
times = np.arange(len(images)) / 29.92
tracker = HolisticTracker()
landmarks = [tracker.process(image) for image in images]
tracker.close()
fig, ax = plt.subplots(figsize=(6, 3))
jitter = {}
for label, settings in (("no filter", FilterSettings(1000.0, 0.0)), ("default", FilterSettings()),
                        ("min_cutoff 0.3 Hz, beta 0", FilterSettings(0.3, 0.0))):
    reader = CausalReader(settings)
    demos = [reader.read(lm, t) for lm, t in zip(landmarks, times, strict=True)]
    z = np.array([d.arm_positions[0, 1, 2, 2] if d is not None else np.nan for d in demos])
    jitter[label] = 1000 * np.sqrt(np.nanmean(np.diff(z, 2) ** 2))
    ax.plot(times, z, lw=1.2, label=label)
ax.set(xlabel="time [s]", ylabel="right wrist height [m]")
ax.legend(fontsize="small")
plt.show()
Markdown("Frame-to-frame jitter of that height (RMS second difference): "
         + ", ".join(f"{k} **{v:.1f} mm**" for k, v in jitter.items()) + ".")

# %% [markdown]
# ## Keep a session
#
# `view.record(folder)` starts keeping each processed frame's landmarks and the robot's angles (never the
# images); `view.stop()` ends it and writes `NAME.pose` (MediaPipe's landmarks in pose-format's Holistic layout:
# what notebook 08 and `nlo-lab retarget` read), `NAME.npz` and `NAME.csv` (the robot's trajectory, on the
# camera's own time base). Run the next cell, sign for a few seconds, then run the one after it. (Without a
# running camera the cell records the sample video instead.)

# %%
from nlo_lab.lab import work_folder

view.record(work_folder("live"), name="session")
if view.camera != "on":
    view.play_video(recording_path("signer_webcam_58f.mp4"), frames=budget(58, 15))

# %%
session = view.stop()
print({kind: path.name for kind, path in session.files.items()}, f"{len(session)} frames at {session.fps:.1f} fps")

# %% [markdown]
# Both files open like any other: the `.pose` file with the reader of notebook 08 (offline this time: with the
# future frames, smoothing and retiming), the trajectory with `RobotTrajectory.load`. The live trajectory was
# rate limited, so no joint is ever faster than its velocity limit on the camera's time base (the dashed lines).

# %%
from nlo_lab.human import load_demonstration
from nlo_lab.inference import RobotTrajectory
from nlo_lab.metrics import limit_violations, velocity_violations
from nlo_lab.viz import plot_joint_speeds

robot = view.retargeter.robot
demo = load_demonstration(session.files["pose"])
trajectory = RobotTrajectory.load(session.files["trajectory"])
print(f"{demo.name}: {len(demo)} frames at {demo.fps:.1f} fps; trajectory {trajectory.angles.shape}, "
      f"{velocity_violations(robot, trajectory.angles, trajectory.times)} velocity and "
      f"{limit_violations(robot, trajectory.angles)} joint-limit violations")
plot_joint_speeds(robot, {"live": trajectory});

# %% [markdown]
# ## Exercises
#
# 1. Leave the camera's picture for a few seconds. Before you do: what will the robot do, and how fast? (Read
#    `LiveRetargeter`'s `hold_seconds` and `ease_seconds`.) Then come back in and watch the first frames.
# 2. Move `iterations` down to 3 and up to 100. Predict what happens to the frame rate and to how closely the
#    robot's wrists follow yours, then check the status line and the latency plot.
# 3. Set `min_cutoff` to 0.2 Hz and `beta` to 0, then wave fast. What do you expect to see, and why is it
#    the price of a filter that may not look at the future?
# 4. Record a sign, then retarget the `.pose` file offline with `retarget` (notebook 08) and compare the two
#    trajectories with `plot_joint_speeds`. Which one is slower than your signing, and why?
# 5. Start the view with `CameraView(robot="nao")`. Which of your movements can NAO not follow, and what does
#    its view do instead?
