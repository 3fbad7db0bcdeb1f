"""``nlo-lab demo``: the bundled robots' joint tables, then a corpus clip retargeted to YuMi into ``out/demo``."""

from __future__ import annotations

import argparse
from pathlib import Path

from nlo_lab.cli import retarget
from nlo_lab.cli.flags import Parser
from nlo_lab.paths import BUNDLED_ROBOTS

__all__ = ["DEMO_CLIP", "add_parser", "run"]

DEMO_CLIP = "demo:introduction_06"  # "HELLO, NAME, STUDENT" (133 frames at 20 fps)


def add_parser(subparsers) -> argparse.ArgumentParser:
    return subparsers.add_parser("demo", help="retarget a clip of the embedded test split to YuMi and print the summary")


def run(args) -> int:
    from nlo_lab.robot import load_robot

    for name in BUNDLED_ROBOTS:
        robot = load_robot(name)
        print(f"\n{name}: {robot.n_joints} actuated joints")
        print(f"  {'joint':<40} {'lower':>9} {'upper':>9}")
        for joint, lo, hi in zip(robot.joint_names, robot.lower_limits.tolist(), robot.upper_limits.tolist(), strict=True):
            print(f"  {joint:<40} {lo:>9.4f} {hi:>9.4f}")
    out = Path("out/demo")
    print(f"\nretargeting {DEMO_CLIP} to yumi ...")
    parser = Parser(prog="nlo-lab")  # the retarget command's own flags and defaults
    retarget.add_parser(parser.add_subparsers(dest="command"))
    return retarget.run(parser.parse_args(["retarget", DEMO_CLIP, "--robot", "yumi", "--out", str(out)]))
