"""Notebook 03's weight sliders move pictures: the pose (3-D view) and the chart of the weighted terms."""

from __future__ import annotations

import numpy as np
import pytest

from nlo_lab.corpus import corpus_clip, corpus_names
from nlo_lab.errors import SettingsError
from nlo_lab.lab import WeightsPanel
from nlo_lab.objective import LossWeights, targets_from_demonstration
from nlo_lab.viz.widget import unpack_commands


@pytest.fixture(scope="module")
def frame(robots):
    robot = robots["yumi"]
    demo = corpus_clip(corpus_names("test")[0])
    t = len(demo) // 2
    targets = targets_from_demonstration(demo, dtype=robot.lower_limits.dtype)
    return robot, targets.index(slice(t, t + 1)), demo.slice(t, t + 1)


def _robot_transforms(widget) -> dict[str, list]:
    return {c["path"]: c["matrix"] for c in unpack_commands(widget.snapshot())
            if c["type"] == "set_transform" and c["path"].startswith("/meshcat/robot")}


def test_a_weight_moves_the_pose_the_view_and_the_chart(frame):
    robot, one, human = frame
    panel = WeightsPanel(robot, one, human, iterations=15)
    view = panel._view.widget
    q, pose, chart, total = panel.q.copy(), _robot_transforms(view), bytes(panel.chart.value), panel.total
    assert chart.startswith(b"\x89PNG") and "finger" in panel.status.value
    sent = view.messages_sent
    panel.sliders["finger"].value = 0.1                 # as a release of the slider in the browser
    assert panel.weights == LossWeights(finger=0.1)
    assert np.abs(panel.q - q).max() > 1e-3              # optimised again with the new weights
    assert _robot_transforms(view) != pose               # the view shows the new pose
    assert view.messages_sent == sent + 1                # in one message
    assert bytes(panel.chart.value) != chart and panel.total != total
    assert panel.error == ""


def test_the_same_weights_give_the_same_pose(frame):
    robot, one, human = frame
    a = WeightsPanel(robot, one, human, iterations=10, view=None)
    b = WeightsPanel(robot, one, human, iterations=10, view=None, weights=LossWeights(elbow=1000.0))
    b.sliders["elbow"].value = 100.0
    np.testing.assert_allclose(a.q, b.q)


def test_bad_input_is_refused(frame):
    import torch

    robot, one, human = frame
    with pytest.raises(SettingsError, match="one frame"):
        WeightsPanel(robot, one.index(torch.tensor([0, 0])), view=None)
    with pytest.raises(SettingsError, match="iterations"):
        WeightsPanel(robot, one, human, iterations=0, view=None)
