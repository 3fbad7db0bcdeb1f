"""Animations loop until paused: show_view, show_human and the exported viewer page.

three.js's LoopRepeat stops after ``repetitions`` passes, so the page must receive infinity
(0 or 1 plays once). A retarget panel's animation plays once: its Play slider ends with it.
"""

from __future__ import annotations

import base64
import math
import re

import numpy as np
import umsgpack

from nlo_lab.corpus import corpus_clip, corpus_names
from nlo_lab.lab import show_human, show_robot, show_view
from nlo_lab.viz import static_html
from nlo_lab.viz.widget import unpack_commands


def _animations(commands: list[dict]) -> list[dict]:
    return [c for c in commands if c["type"] == "set_animation"]


def _motion(robot, frames: int = 6) -> np.ndarray:
    lo, hi = robot.lower_limits.numpy(), robot.upper_limits.numpy()
    return np.linspace(0.6 * lo + 0.4 * hi, 0.4 * lo + 0.6 * hi, frames)


def test_show_view_and_show_human_loop(nao):
    demo = corpus_clip(corpus_names("test")[0]).slice(0, 6)
    for widget in (show_view(nao, _motion(nao)), show_view(nao, _motion(nao), demo=demo), show_human(demo)):
        (anim,) = _animations(unpack_commands(widget.snapshot()))
        assert anim["options"] == {"play": True, "repetitions": math.inf}
        assert anim["animations"]  # tracks to play


def test_one_pose_has_no_animation(nao):
    assert _animations(unpack_commands(show_robot(nao).snapshot())) == []


def test_the_exported_page_loops_when_it_plays(nao):
    def options(page: str) -> dict:
        blobs = re.findall(r"fetch\(\"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)\"\)", page)  # meshcat.servers.zmqserver.create_command
        commands = [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]
        (anim,) = [c for c in commands if isinstance(c, dict) and c.get("type") == "set_animation"]
        return anim["options"]

    assert options(static_html(nao, _motion(nao))) == {"play": True, "repetitions": math.inf}
    assert options(static_html(nao, _motion(nao), play=False)) == {"play": False, "repetitions": 1}
