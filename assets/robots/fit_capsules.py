"""Fit a bundled robot's collision capsules and checked pairs to its URDF's collision geometry.

    .venv/bin/python assets/robots/fit_capsules.py [yumi nao pepper]

Rewrites ``capsules``, ``collision_pairs`` and ``collision_margin`` of ``NAME.json`` with
``nlo_lab.robot.capsule_draft.draft_collision`` (what ``nlo-lab robot init`` does for any URDF):
capsules that hold every ``<collision>`` element, pairs that can collide, thinned copies where
fat capsules would block what the geometry allows. The margin's ``default`` is kept; per-pair
margins are dropped (the hands' capsules they named are gone). The rest pose is the spec's
``neutral_pose`` (YuMi's zero pose crosses the forearms).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from nlo_lab.robot import load_robot
from nlo_lab.robot.capsule_draft import Arms, draft_collision
from nlo_lab.robot.spec import spec_text

HERE = Path(__file__).resolve().parent


def fit(name: str) -> dict:
    """The new collision fields of robot ``name`` (its spec as it is now gives the arms and the rest pose)."""
    path = HERE / f"{name}.json"
    robot = load_robot(path)
    arms = Arms({s: set(robot.model.subtree(robot.arm(s).shoulder)) for s in ("left", "right")},
                {s: robot.arm(s).wrist for s in ("left", "right")})
    default = json.loads(path.read_text(encoding="utf-8"))["collision_margin"]["default"]
    draft = draft_collision(robot.model, robot.tree, robot.neutral_q.double().numpy(),
                            robot.lower_limits.double().numpy(), robot.upper_limits.double().numpy(), arms, default)
    print(f"{name}: {len(draft.capsules)} capsules, {len(draft.pairs)} pairs ({draft.thinned} thinned, "
          f"{draft.far} never near, {len(draft.touching)} link pairs touching at rest)")
    return {
        "capsules": [{"name": c.name, "link": c.link, "p0": list(c.p0), "p1": list(c.p1), "radius": c.radius} for c in draft.capsules],
        "collision_pairs": [list(p) for p in draft.pairs],
        "collision_margin": {"default": default},
    }


def update(name: str) -> None:
    path = HERE / f"{name}.json"
    spec = json.loads(path.read_text(encoding="utf-8"))
    spec.update(fit(name))
    path.write_text(spec_text(spec), encoding="utf-8")


if __name__ == "__main__":
    for robot_name in sys.argv[1:] or ["yumi", "nao", "pepper"]:
        update(robot_name)
