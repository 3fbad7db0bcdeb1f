"""How live the notebook panel feels: time to re-optimise the current frame after a slider move.

Target (docs/DESIGN.md, "Targets"): one frame re-optimised after a slider move (<= 30 iterations) in
<= 50 ms median. The panel warm-starts from the frame's previous latent and
stops after 5 iterations without improvement, as a learner would use it.

    .venv/bin/python benchmarks/panel.py [--robot yumi] [--clip introduction_06]
"""

from __future__ import annotations

import argparse
import statistics

import torch

from nlo_lab.corpus import corpus_clip
from nlo_lab.lab import RetargetPanel


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="yumi")
    parser.add_argument("--clip", default="introduction_06")
    parser.add_argument("--frames", type=int, default=40, help="frame-scrubber moves")
    args = parser.parse_args()
    torch.set_num_threads(1)
    panel = RetargetPanel(corpus_clip(args.clip), args.robot, view=None)
    seconds, steps = [], []

    def record() -> None:
        seconds.append(panel.last_seconds)
        steps.append(panel.last.iterations)

    for frame in range(1, args.frames + 1):  # scrub: each frame re-optimised, warm-started
        panel.controls["frame"].value = frame
        record()
    for weight in (500.0, 2000.0, 1000.0, 300.0, 3000.0):  # move the end-effector weight slider
        panel.controls["ee"].value = weight
        record()
    ms = sorted(1000 * s for s in seconds)
    print(f"robot {args.robot}, clip {args.clip}: {len(ms)} slider moves")
    print(f"re-optimise one frame: median {statistics.median(ms):.1f} ms, p90 {ms[int(0.9 * len(ms))]:.1f} ms (target <= 50 ms median)")
    print(f"iterations per move: median {statistics.median(steps):g}, max {max(steps)} (budget 30)")


if __name__ == "__main__":
    main()
