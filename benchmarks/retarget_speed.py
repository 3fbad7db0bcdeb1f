"""Speed and quality of neural latent optimisation (prints a table).

    python benchmarks/retarget_speed.py [--robot yumi] [--checkpoint PATH] [--clips N] [--threads 1] [--all]

1. Retarget a 170-frame two-arm, two-hand clip (frames of the synthetic test
   split) with 100 iterations (target <= 1.5 s), and the time of one iteration
   at batch 170 and 1 split into decoder / FK (with the objective's points) /
   capsules / remaining loss terms / backward / Adam step.
2. Re-optimise one frame with 30 iterations, warm-started (target <= 50 ms median).
3. Mean Fréchet distance (wrist + elbow, docs/DESIGN.md, "Metric") on the test split:
   encoder output alone vs encoder-initialised latent optimisation (target >= 10 %
   lower), plus zeros/random initialisation and the joint-space baseline.
"""

from __future__ import annotations

import argparse
import statistics
import time

import torch

from nlo_lab.corpus import sign_corpus
from nlo_lab.human.demonstration import Demonstration
from nlo_lab.inference import JointOptimizeSettings, OptimizeSettings, RetargetInputs, optimize_joints, optimize_latent
from nlo_lab.metrics import tracking_errors
from nlo_lab.model import EncoderInput, load_checkpoint, load_pretrained
from nlo_lab.objective import Targets
from nlo_lab.robot import load_robot


def concat_demos(demos: list[Demonstration], frames: int) -> Demonstration:
    """The first ``frames`` frames of the concatenated clips."""
    import numpy as np

    keys = ("arm_positions", "arm_mask", "wrist_rotations", "wrist_mask", "finger_positions", "finger_mask")
    arrays = {k: np.concatenate([getattr(d, k) for d in demos])[:frames] for k in keys}
    return Demonstration(fps=demos[0].fps, name=f"{frames} frames", **arrays)


def latent(model, robot, demo: Demonstration, settings: OptimizeSettings, **options):
    """Targets and encoder input of ``demo`` (timed with the optimisation), then :func:`optimize_latent`."""
    x = RetargetInputs.from_demonstration(demo)
    return optimize_latent(model, robot, x.targets, settings, encoder_input=x.encoder, fast=True, **options)


def profile_iteration(model, robot, targets: Targets, features: EncoderInput, reps: int = 20) -> dict[str, float]:
    """Median wall time [ms] of each stage of one latent-optimisation iteration (the optimiser's own path)."""
    from nlo_lab.inference import Adam as _Adam
    from nlo_lab.objective import Objective

    z = model.encode(features.node_features, features.edge_features).detach().requires_grad_(True)
    for p in model.parameters():
        p.requires_grad_(False)
    from nlo_lab.inference import FastPaths

    paths = FastPaths.for_frames(len(targets))  # what the optimiser runs
    loss_fn = Objective(robot, targets, **paths.objective_options())
    adam = _Adam(z, 0.01)
    parts: dict[str, list[float]] = {k: [] for k in ("decoder", "fk points", "loss terms", "backward", "adam")}
    for _ in range(reps):
        t0 = time.perf_counter()
        q = model.decode(z, paths.decoder)
        t1 = time.perf_counter()
        loss_fn.plan.map(q, paths.analytic_fk)  # FK + every point the terms need (timed alone)
        t2 = time.perf_counter()
        total, _ = loss_fn(q)  # FK points again + the terms; the FK time is subtracted below
        loss = torch.add(total, z.pow(2).flatten(1).sum(1))
        t3 = time.perf_counter()
        (g,) = torch.autograd.grad(loss.sum(), z)
        t4 = time.perf_counter()
        adam.update(z, g)
        t5 = time.perf_counter()
        for k, dt in zip(parts, (t1 - t0, t2 - t1, (t3 - t2) - (t2 - t1), t4 - t3, t5 - t4), strict=True):
            parts[k].append(dt * 1000)
    for p in model.parameters():
        p.requires_grad_(True)
    return {k: statistics.median(v) for k, v in parts.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robot", default="yumi")
    ap.add_argument("--checkpoint", default=None)
    ap.add_argument("--clips", type=int, default=25, help="test clips for the Fréchet comparison")
    ap.add_argument("--threads", type=int, default=1, help="2 threads oversubscribe when other work shares the cores (10x slower measured)")
    ap.add_argument("--all", action="store_true", help="also zeros/random initialisation and the joint-space baseline")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    robot = load_robot(args.robot)
    model = load_checkpoint(args.checkpoint, robot) if args.checkpoint else load_pretrained(robot)
    test = sign_corpus("test")
    print(f"robot {robot.name}, {robot.n_joints} joints, torch threads {torch.get_num_threads()}")

    # 1. 170-frame clip, 100 iterations.
    clip = concat_demos(test, 170)
    settings = OptimizeSettings(init="encoder", iterations=100, patience=100)  # no early stop: the full budget
    latent(model, robot, clip, OptimizeSettings(iterations=3))  # warm-up
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        r = latent(model, robot, clip, settings)
        times.append(time.perf_counter() - t0)
    print(f"170 frames x 100 iterations: {statistics.median(times):.3f} s median of 3 (target <= 1.5 s), "
          f"{r.iterations} steps, loss {r.history[0]:.1f} -> {min(r.history):.1f}")
    for frames in (170, 1):
        x = RetargetInputs.from_demonstration(clip).index(slice(0, frames))
        parts = profile_iteration(model, robot, x.targets, x.encoder, reps=20 if frames > 1 else 200)
        print(f"  per iteration at batch {frames} [ms, median]: " + ", ".join(f"{k} {v:.2f}" for k, v in parts.items()) + f"; sum {sum(parts.values()):.2f}")
    t_def = time.perf_counter()
    r = latent(model, robot, clip, OptimizeSettings())
    print(f"  with the default stop (patience 5): {time.perf_counter() - t_def:.3f} s, {r.iterations} steps")

    # 2. One frame, 30 iterations, warm-started from the clip's result.
    one = RetargetInputs.from_demonstration(clip).targets.index(slice(80, 81))
    z_prev = r.z[79:80]
    ms = []
    for _ in range(20):
        t0 = time.perf_counter()
        optimize_latent(model, robot, one, OptimizeSettings(iterations=30, patience=30), z0=z_prev, fast=True)
        ms.append((time.perf_counter() - t0) * 1000)
    print(f"1 frame x 30 iterations: {statistics.median(ms):.1f} ms median of 20 (target <= 50 ms)")

    # 3. Fréchet on the test split.
    rows = {"encoder only": [], "encoder + latent opt": [], "zeros + latent opt": [], "random + latent opt": [], "joint space (clamp)": []}
    secs = {k: 0.0 for k in rows}
    for demo in test[: args.clips]:
        x = RetargetInputs.from_demonstration(demo)
        t = x.targets
        runs = {  # each run binds this clip's targets and inputs
            "encoder only": lambda t=t, x=x: optimize_latent(model, robot, t, OptimizeSettings(iterations=0), encoder_input=x.encoder, fast=True),
            "encoder + latent opt": lambda t=t, x=x: optimize_latent(model, robot, t, OptimizeSettings(), encoder_input=x.encoder, fast=True),
            "zeros + latent opt": lambda t=t: optimize_latent(model, robot, t, OptimizeSettings(init="zeros"), fast=True),
            "random + latent opt": lambda t=t: optimize_latent(model, robot, t, OptimizeSettings(init="random"), fast=True),
            "joint space (clamp)": lambda t=t: optimize_joints(robot, t, JointOptimizeSettings(), fast=True),
        }
        if not args.all:
            runs = {k: runs[k] for k in ("encoder only", "encoder + latent opt")}
        for name, run in runs.items():
            t0 = time.perf_counter()
            res = run()
            secs[name] += time.perf_counter() - t0
            rows[name].append(tracking_errors(demo, robot, res.q)["frechet_m"])
    if not rows["encoder only"]:
        return
    base = statistics.mean(rows["encoder only"])
    print(f"mean Fréchet (wrist+elbow) on {len(rows['encoder only'])} test clips:")
    for name, values in rows.items():
        if not values:
            continue
        m = statistics.mean(values)
        print(f"  {name:<22} {m:.4f} m  ({100 * (m - base) / base:+.1f} % vs encoder only)  {secs[name]:.1f} s total")


if __name__ == "__main__":
    main()
